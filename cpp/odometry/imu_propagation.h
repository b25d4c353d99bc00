// IMU forward propagation with GTSAM's tangent-space preintegration scheme (so a propagated state equals
// gtsam.PreintegratedCombinedMeasurements.predict from the same start state and biases).
//
// Sample k (accelerometer f_k, gyroscope w_k, in the IMU frame I) is held over dt_k. With a = f_k - b_a and
// w = w_k - b_g, the preintegrated rotation vector theta, position dP and velocity dV (in the start frame) update
//     dP += dV dt + 1/2 Exp(theta) a dt^2,   dV += Exp(theta) a dt,   theta += Jr^-1(theta) w dt
// and the state after k samples is R_k = R_0 Exp(theta), p_k = p_0 + v_0 t + 1/2 g t^2 + R_0 dP,
// v_k = v_0 + g t + R_0 dV (t: time since the start). The state is the IMU frame's pose in the world.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>

namespace cufund::odometry {

struct NavState {
  Eigen::Vector3d p_W = Eigen::Vector3d::Zero();
  Eigen::Vector3d v_W = Eigen::Vector3d::Zero();
  Eigen::Matrix3d R_WI = Eigen::Matrix3d::Identity();
};

Eigen::Matrix3d so3_exp(const Eigen::Vector3d& w);
Eigen::Matrix3d skew(const Eigen::Vector3d& w);

// Propagates `start` through n samples. dt: (n,), acc/gyr: (n, 3) row-major.
// states: (n + 1, 10) row-major [p_W, v_W, q_WI (w, x, y, z)], row 0 = start.
// rates (optional, may be null): (n, 6) row-major [a_W, w_I], the bias-corrected world acceleration (gravity
// included) and IMU-frame angular rate held over sample k: what deskewing interpolates with.
void propagate(const NavState& start, const Eigen::Vector3d& bias_acc, const Eigen::Vector3d& bias_gyr,
               const Eigen::Vector3d& gravity_W, const double* dt, const double* acc, const double* gyr, std::size_t n,
               double* states, double* rates);

}  // namespace cufund::odometry
