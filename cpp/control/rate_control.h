// PX4-style body-rate control (mc_rate_control) followed by control allocation, one step per call: PID with the
// derivative on the low-passed measured rate, integrator anti-windup on the allocator's saturation. The
// arithmetic of python/cufund/control/rate_control.py in the same order (see reference_arithmetic.h).
#pragma once

#include <Eigen/Core>

#include "allocation.h"
#include "loop_state.h"

namespace cufund {

struct RateControlGains {
  Eigen::Vector3d k_p;      // [rad/s^2 per rad/s]
  Eigen::Vector3d k_i;      // [rad/s^2 per rad]
  Eigen::Vector3d k_d;      // [rad/s^2 per rad/s^2]
  double feed_forward;      // [rad/s^2 per rad/s]
  double integrator_limit;  // [rad/s^2]
};

class RateControl {
 public:
  // d_cutoff_hz: the rate derivative's low-pass (0: none); i_scale [rad/s]: the rate error at which the
  // integrator stops growing (PX4: 400 deg/s).
  RateControl(const QuadrotorParams& params, double d_cutoff_hz, double i_scale);

  void set_gains(const RateControlGains& gains) { gains_ = gains; }
  void reset();

  // One step with measured body rate w_B [rad/s] towards w_sp [rad/s] and collective thrust [N], dt [s] after
  // the previous one.
  AllocationResult step(const Eigen::Vector3d& w_B, const Eigen::Vector3d& w_sp, double thrust, double dt);

  const ControlAllocator& allocator() const { return allocator_; }

  Eigen::Vector3d rate_int = Eigen::Vector3d::Zero();  // integrator [rad/s^2]
  // filtered measured angular acceleration [rad/s^2]
  const Eigen::Vector3d& dw_filt() const { return dw_filter_.value; }

 private:
  ControlAllocator allocator_;
  Eigen::Matrix3d J_;
  RateControlGains gains_{};
  double i_scale_;
  LowPassDerivative dw_filter_;
};

}  // namespace cufund
