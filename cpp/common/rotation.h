// The rotation matrix of a quaternion [w, x, y, z], for the casters and scan placement that take poses as raw
// double arrays (Eigen users have Eigen::Quaterniond::toRotationMatrix).
#pragma once

#include <cmath>

namespace cufund {

// Row-major R (3 x 3) of the quaternion q = [w, x, y, z], normalised here: q is divided by its norm first, so any
// non-zero q gives a rotation (the callers check q is non-zero and finite). R maps the quaternion's child frame
// into its parent: for q_WS, v_W = R v_S.
inline void quat_to_rotation(const double* q, double R[9]) {
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  const double w = q[0] / n, x = q[1] / n, y = q[2] / n, z = q[3] / n;
  R[0] = 1 - 2 * (y * y + z * z);
  R[1] = 2 * (x * y - w * z);
  R[2] = 2 * (x * z + w * y);
  R[3] = 2 * (x * y + w * z);
  R[4] = 1 - 2 * (x * x + z * z);
  R[5] = 2 * (y * z - w * x);
  R[6] = 2 * (x * z - w * y);
  R[7] = 2 * (y * z + w * x);
  R[8] = 1 - 2 * (x * x + y * y);
}

}  // namespace cufund
