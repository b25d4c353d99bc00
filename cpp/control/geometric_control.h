// The attitude part of the nonlinear geometric controller on SE(3) (Lee, Leok & McClamroch, CDC 2010), in
// world ENU / body FLU, with gains as accelerations per unit error (multiplied by J here):
//   e_R = 1/2 vee(R_d^T R - R^T R_d),  e_W = W - R^T R_d W_d,
//   M = J(-k_R e_R - k_W e_W) + W x J W - J (W x R^T R_d W_d)        (dW_d taken as zero)
#pragma once

#include <Eigen/Core>

namespace cufund {

struct GeometricAttitudeCommand {
  double thrust;             // collective [N], >= 0
  Eigen::Vector3d torque_B;  // [N m]
  Eigen::Vector4d q_WB_d;    // desired attitude [w, x, y, z], w >= 0
};

// R_WB with body z along unit z_B and body x along the heading yaw, projected (PX4's bodyzToAttitude).
Eigen::Matrix3d attitude_from_thrust_and_yaw(const Eigen::Vector3d& z_B, double yaw);

// Position and velocity modes: from the desired force F_W [N] (Lee's m g e3 - k_x e_x - k_v e_v + m a_d), the
// jerk feed-forward j_W [m/s^3] (for the desired body rate by differential flatness), yaw and yaw rate.
GeometricAttitudeCommand geometric_from_force(const Eigen::Matrix3d& J, double mass, const Eigen::Vector3d& k_R,
                                              const Eigen::Vector3d& k_W, const Eigen::Vector4d& q_WB,
                                              const Eigen::Vector3d& w_B, const Eigen::Vector3d& F_W,
                                              const Eigen::Vector3d& j_W, double yaw, double yaw_rate);

// Attitude mode: a desired attitude, collective thrust [N] and yaw rate [rad/s].
GeometricAttitudeCommand geometric_from_attitude(const Eigen::Matrix3d& J, const Eigen::Vector3d& k_R,
                                                 const Eigen::Vector3d& k_W, const Eigen::Vector4d& q_WB,
                                                 const Eigen::Vector3d& w_B, const Eigen::Vector4d& q_WB_d,
                                                 double thrust, double yaw_rate);

}  // namespace cufund
