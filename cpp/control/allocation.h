// Control allocation with priorities (PX4's multicopter mixer with air mode): collective thrust and body
// torque to rotor speeds within the motor limits, keeping roll/pitch authority when motors saturate.
#pragma once

#include <Eigen/Core>
#include <array>

#include "mixer.h"
#include "quadrotor_params.h"

namespace cufund {

struct AllocationResult {
  Vector4d rotor_speeds;  // commands [rad/s], PX4 numbering
  Vector4d achieved;      // [f, M_x, M_y, M_z] the commands produce (before the motors' lag)
  // Per [f, M_x, M_y, M_z]: +1 the demand exceeded what was achieved, -1 fell below it, 0 met (anti-windup).
  std::array<int, 4> saturation;
};

class ControlAllocator {
 public:
  explicit ControlAllocator(const QuadrotorParams& params);
  // In rotor-thrust space: (1) roll/pitch differences are scaled down only if they alone span more than the
  // motors' range; (2) the collective is shifted (up or down) by the least amount that puts every rotor in
  // range; (3) as much of the yaw torque is added as still fits.
  AllocationResult allocate(double thrust, const Eigen::Vector3d& torque_B) const;
  double max_thrust() const { return 4.0 * u_max_; }

 private:
  Matrix4d A_, A_inv_;
  double k_f_, u_min_, u_max_;
};

}  // namespace cufund
