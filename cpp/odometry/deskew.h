// Per-point motion compensation to one reference time (FAST-LIO2's backward pass).
//
// The IMU trajectory is given as knots: IMU-frame states at times knot_t (K,) [p_W, v_W, q_WI (w,x,y,z)] and,
// held over [knot_t[k], knot_t[k+1]), the world acceleration a_W and IMU rate w_I (K-1 rows; what propagate()
// returns as `rates`). A point fired at time tau in interval k is seen from
//     R_WI(tau) = R_k Exp(w_k s),   p_WI(tau) = p_k + v_k s + 1/2 a_k s^2,   s = tau - knot_t[k]
// (times before the first or after the last knot use the first or last interval), and is moved to the LiDAR
// frame at t_ref:  p_L(ref) = T_IL^-1 T_WI(ref)^-1 T_WI(tau) T_IL p_L(tau),  with T_IL = T_BI^-1 T_BL.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>

namespace cufund::odometry {

struct Trajectory {
  const double* knot_t = nullptr;  // (K,) increasing
  const double* states = nullptr;  // (K, 10)
  const double* rates = nullptr;   // (K - 1, 6); K >= 2
  std::size_t knots = 0;
};

// T_WI at time tau (R, p).
void pose_at(const Trajectory& traj, double tau, Eigen::Matrix3d& R_WI, Eigen::Vector3d& p_W);

// points_L: (n, 3) float32; t_points: (n,) absolute firing times; out: (n, 3) float64 in L at t_ref.
void deskew(const float* points_L, const double* t_points, std::size_t n, const Trajectory& traj, double t_ref,
            const Eigen::Isometry3d& T_BI, const Eigen::Isometry3d& T_BL, double* out, int threads);

}  // namespace cufund::odometry
