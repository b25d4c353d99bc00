// The attitude part of the nonlinear geometric controller on SE(3) (Lee, Leok & McClamroch, CDC 2010), in
// world ENU / body FLU, with gains as accelerations per unit error (multiplied by J here):
//   e_R = 1/2 vee(R_d^T R - R^T R_d),  e_W = W - R^T R_d W_d,
//   M = J(-k_R e_R - k_W e_W) + W x J W - J (W x R^T R_d W_d)        (dW_d taken as zero)
#pragma once

#include <Eigen/Core>

#include "allocation.h"
#include "loop_state.h"

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

// The whole controller as one object, gains and vehicle fixed, for one call per step: the force law (with the
// bumpless hand-over at a mode switch), the attitude law above and the prioritising allocation.
struct GeometricStep {
  GeometricAttitudeCommand command;
  AllocationResult allocation;
};

class GeometricControl {
 public:
  // transfer_tau [s]: decay of the step a mode switch would cause in the force command.
  GeometricControl(const QuadrotorParams& params, double transfer_tau);

  // k_x [m/s^2 per m], k_v [m/s^2 per m/s] (times the mass), k_R, k_W per body axis (times J).
  void set_gains(double k_x, double k_v, const Eigen::Vector3d& k_R, const Eigen::Vector3d& k_W);
  void reset() { handover_.reset(); }

  // Position (position_mode) or velocity mode at time t [s]: F = m (a_sp - k_v (v - v_sp)) + m g e3
  // [- k_x m (p - p_sp)], plus the faded hand-over (handover, non-null at a mode switch: the force last
  // commanded [N]); q_WB unit.
  GeometricStep step_force(double t, const Eigen::Vector3d& p_W, const Eigen::Vector3d& v_W,
                           const Eigen::Vector4d& q_WB, const Eigen::Vector3d& w_B, const Eigen::Vector3d& p_sp,
                           const Eigen::Vector3d& v_sp, const Eigen::Vector3d& a_sp, const Eigen::Vector3d& j_sp,
                           double yaw, double yaw_rate, bool position_mode, const Eigen::Vector3d* handover);

  // Attitude mode: a desired attitude (unit), collective thrust [N] and yaw rate [rad/s].
  GeometricStep step_attitude(const Eigen::Vector4d& q_WB, const Eigen::Vector3d& w_B, const Eigen::Vector4d& q_WB_d,
                              double thrust, double yaw_rate) const;

 private:
  ControlAllocator allocator_;
  Eigen::Matrix3d J_;
  double mass_, gravity_;
  double k_x_ = 0.0, k_v_ = 0.0;
  Eigen::Vector3d k_R_ = Eigen::Vector3d::Zero(), k_W_ = Eigen::Vector3d::Zero();
  BumplessHandover handover_;
};

}  // namespace cufund
