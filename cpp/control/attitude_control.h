// PX4-style attitude control (mc_att_control): P on the quaternion error with reduced yaw priority, the
// arithmetic of python/cufund/control/attitude_control.py in the same order (see reference_arithmetic.h).
#pragma once

#include <Eigen/Core>

namespace cufund {

// Body-rate setpoint [rad/s] for attitude q_WB towards q_WB_d ([w, x, y, z], unit): gains k [1/s] (roll, pitch,
// and their mean for the reduced-priority error), the yaw weight in [0, 1], the yaw-rate feed-forward about
// world z [rad/s], limited to +-rate_max per axis.
Eigen::Vector3d attitude_rate_setpoint(const Eigen::Vector4d& q_WB, const Eigen::Vector4d& q_WB_d, double yaw_rate,
                                       const Eigen::Vector3d& k, const Eigen::Vector3d& rate_max, double yaw_weight);

// The gains of attitude_rate_setpoint, set once (the binding's handle on them).
struct AttitudeControl {
  Eigen::Vector3d k = Eigen::Vector3d::Zero();
  Eigen::Vector3d rate_max = Eigen::Vector3d::Zero();
  double yaw_weight = 0.0;
};

// The shortest rotation taking unit vector u to unit vector v (PX4's Quatf(u, v)), as the Python reference.
Eigen::Vector4d quat_from_two_vectors(const Eigen::Vector3d& u, const Eigen::Vector3d& v);

// Hamilton product a * b, quaternions [w, x, y, z].
Eigen::Vector4d quat_multiply(const Eigen::Vector4d& a, const Eigen::Vector4d& b);

}  // namespace cufund
