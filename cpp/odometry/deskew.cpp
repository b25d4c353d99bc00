#include "deskew.h"

#include <algorithm>
#include <vector>

#include "imu_propagation.h"
#include "thread_pool.h"

namespace cufund::odometry {

namespace {

// pose_at with the knots' rotation matrices precomputed (R_knots may be null: from the quaternions).
void pose_at_impl(const Trajectory& traj, const Eigen::Matrix3d* R_knots, double tau, Eigen::Matrix3d& R_WI,
                  Eigen::Vector3d& p_W) {
  // Interval k: the last knot at or before tau, clamped to [0, K-2].
  const double* end = traj.knot_t + traj.knots;
  std::ptrdiff_t k = std::upper_bound(traj.knot_t, end, tau) - traj.knot_t - 1;
  k = std::clamp<std::ptrdiff_t>(k, 0, static_cast<std::ptrdiff_t>(traj.knots) - 2);
  const double* s = traj.states + 10 * k;
  const double* r = traj.rates + 6 * k;
  const double h = tau - traj.knot_t[k];
  const Eigen::Vector3d w(r[3], r[4], r[5]);
  const Eigen::Matrix3d R_k =
      R_knots ? R_knots[k] : Eigen::Quaterniond(s[6], s[7], s[8], s[9]).normalized().toRotationMatrix();
  R_WI = R_k * so3_exp(w * h);
  p_W = Eigen::Vector3d(s[0], s[1], s[2]) + Eigen::Vector3d(s[3], s[4], s[5]) * h +
        Eigen::Vector3d(r[0], r[1], r[2]) * (0.5 * h * h);
}

}  // namespace

void pose_at(const Trajectory& traj, double tau, Eigen::Matrix3d& R_WI, Eigen::Vector3d& p_W) {
  pose_at_impl(traj, nullptr, tau, R_WI, p_W);
}

void deskew(const float* points_L, const double* t_points, std::size_t n, const Trajectory& traj, double t_ref,
            const Eigen::Isometry3d& T_BI, const Eigen::Isometry3d& T_BL, double* out, int threads) {
  const Eigen::Isometry3d T_IL = T_BI.inverse() * T_BL;
  Eigen::Matrix3d R_ref;
  Eigen::Vector3d p_ref;
  pose_at(traj, t_ref, R_ref, p_ref);
  Eigen::Isometry3d T_WI_ref = Eigen::Isometry3d::Identity();
  T_WI_ref.linear() = R_ref;
  T_WI_ref.translation() = p_ref;
  const Eigen::Isometry3d T_LW_ref = T_IL.inverse() * T_WI_ref.inverse();
  std::vector<Eigen::Matrix3d> R_knots(traj.knots);
  for (std::size_t k = 0; k < traj.knots; ++k) {
    const double* s = traj.states + 10 * k;
    R_knots[k] = Eigen::Quaterniond(s[6], s[7], s[8], s[9]).normalized().toRotationMatrix();
  }
  parallel_chunks(static_cast<std::ptrdiff_t>(n), 4096, threads, [&](std::ptrdiff_t b, std::ptrdiff_t e, std::ptrdiff_t) {
    Eigen::Matrix3d R;
    Eigen::Vector3d p;
    for (std::ptrdiff_t i = b; i < e; ++i) {
      pose_at_impl(traj, R_knots.data(), t_points[i], R, p);
      const Eigen::Vector3d x_L(points_L[3 * i], points_L[3 * i + 1], points_L[3 * i + 2]);
      const Eigen::Vector3d x_W = R * (T_IL * x_L) + p;
      Eigen::Map<Eigen::Vector3d>(out + 3 * i) = T_LW_ref * x_W;
    }
  });
}

}  // namespace cufund::odometry
