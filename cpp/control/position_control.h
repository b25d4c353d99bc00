// PX4-style multicopter position control (mc_pos_control), one step per call: position P -> velocity PID with
// the D term on the low-passed measured acceleration -> acceleration -> limited thrust vector -> attitude
// setpoint. The flight-mode logic (which references are active) stays with the caller; this is the arithmetic
// of python/cufund/control/position_control.py, in the same order (see reference_arithmetic.h).
#pragma once

#include <Eigen/Core>

#include "loop_state.h"

namespace cufund {

struct PositionControlGains {
  Eigen::Vector3d k_p;  // position [1/s]
  Eigen::Vector3d k_v;  // velocity P [m/s^2 per m/s]
  Eigen::Vector3d k_i;  // velocity I [m/s^3 per m/s]
  Eigen::Vector3d k_d;  // velocity D on the measured acceleration [m/s^2 per m/s^2]
  double xy_vel_max;    // [m/s]
  double z_vel_max_up;  // [m/s]
  double z_vel_max_dn;  // [m/s]
  double tilt_max;      // [rad]
  double thr_min;       // fraction of the maximum thrust
  double thr_max;       // fraction of the maximum thrust
};

struct PositionControlOutput {
  Eigen::Vector4d q_WB;  // attitude setpoint [w, x, y, z], w >= 0
  double thrust;         // collective [N]
};

class PositionControl {
 public:
  // mass [kg], gravity [m/s^2], max_thrust [N]; vel_d_cutoff_hz: the derivative's low-pass (0: none);
  // transfer_tau [s]: decay of the bumpless hand-over at a mode switch.
  PositionControl(double mass, double gravity, double max_thrust, double vel_d_cutoff_hz, double transfer_tau);

  void set_gains(const PositionControlGains& gains) { gains_ = gains; }
  void reset();

  // The measured velocity's low-passed derivative, stepped by dt [s] (run in every mode, so D does not kick).
  const Eigen::Vector3d& filter_velocity(const Eigen::Vector3d& v_W, double dt);

  // One step at time t [s] (filter_velocity included). position_mode: track p_sp (else only v_sp). handover
  // (non-null at a mode switch): the acceleration last commanded, which continues and fades into the new one.
  PositionControlOutput step(double t, double dt, const Eigen::Vector3d& p_W, const Eigen::Vector3d& v_W,
                             const Eigen::Vector3d& p_sp, const Eigen::Vector3d& v_sp, const Eigen::Vector3d& a_sp,
                             double yaw, bool position_mode, const Eigen::Vector3d* handover);

  // Limits thrust magnitude and tilt; writes the per-axis saturation signs.
  Eigen::Vector3d limit_thrust(Eigen::Vector3d F, Eigen::Vector3i& sat) const;

  Eigen::Vector3d vel_int = Eigen::Vector3d::Zero();                     // velocity integrator [m/s^2]
  const Eigen::Vector3d& acc_filt() const { return acc_filter_.value; }  // filtered measured acceleration [m/s^2]

 private:
  PositionControlGains gains_{};
  double mass_, gravity_, max_thrust_;
  LowPassDerivative acc_filter_;
  BumplessHandover handover_;
};

// Unit quaternion [w, x, y, z] with w >= 0 of a rotation matrix (Shepperd's method), as the Python reference.
Eigen::Vector4d rotation_to_quat(const Eigen::Matrix3d& R);

}  // namespace cufund
