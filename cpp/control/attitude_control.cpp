#include "attitude_control.h"

#include <cmath>

#include "reference_arithmetic.h"

namespace cufund {

namespace ra = reference_arithmetic;

namespace {

Eigen::Vector3d cross(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return Eigen::Vector3d(a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]);
}

Eigen::Vector4d conjugate(const Eigen::Vector4d& q) { return Eigen::Vector4d(q[0], -q[1], -q[2], -q[3]); }

// Third column of R(q) (body z in the world) and its third row (world z in the body).
Eigen::Vector3d body_z(const Eigen::Vector4d& q) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  return Eigen::Vector3d(2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y));
}

Eigen::Vector3d world_z_in_body(const Eigen::Vector4d& q) {
  const double w = q[0], x = q[1], y = q[2], z = q[3];
  return Eigen::Vector3d(2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y));
}

}  // namespace

Eigen::Vector4d quat_multiply(const Eigen::Vector4d& a, const Eigen::Vector4d& b) {
  const double aw = a[0], ax = a[1], ay = a[2], az = a[3];
  const double bw = b[0], bx = b[1], by = b[2], bz = b[3];
  return Eigen::Vector4d(aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                         aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw);
}

Eigen::Vector4d quat_from_two_vectors(const Eigen::Vector3d& u, const Eigen::Vector3d& v) {
  const Eigen::Vector3d c = cross(u, v);
  const double d = ra::dot<3>(u, v);
  if (d < -1.0 + 1e-6) {  // opposite: any axis orthogonal to u
    Eigen::Vector3d axis =
        std::abs(u[0]) < 0.9 ? cross(u, Eigen::Vector3d(1.0, 0.0, 0.0)) : cross(u, Eigen::Vector3d(0.0, 1.0, 0.0));
    const double n = ra::norm<3>(axis);
    for (int i = 0; i < 3; ++i) axis[i] /= n;
    return Eigen::Vector4d(0.0, axis[0], axis[1], axis[2]);
  }
  Eigen::Vector4d q(1.0 + d, c[0], c[1], c[2]);
  const double n = ra::norm<4>(q);
  for (int i = 0; i < 4; ++i) q[i] /= n;
  return q;
}

Eigen::Vector3d attitude_rate_setpoint(const Eigen::Vector4d& q, const Eigen::Vector4d& q_d, double yaw_rate,
                                       const Eigen::Vector3d& k, const Eigen::Vector3d& rate_max, double yaw_weight) {
  Eigen::Vector4d qd_red = quat_from_two_vectors(body_z(q), body_z(q_d));
  if (std::abs(qd_red[1]) > 1 - 1e-5 || std::abs(qd_red[2]) > 1 - 1e-5) {
    qd_red = q_d;  // thrust axes opposite: the full attitude is the only well-defined target
  } else {
    qd_red = quat_multiply(qd_red, q);
  }
  Eigen::Vector4d q_mix = quat_multiply(conjugate(qd_red), q_d);
  if (q_mix[0] < 0) q_mix = -q_mix;
  const double w_mix = ra::clamp(q_mix[0], -1.0, 1.0);
  const double z_mix = ra::clamp(q_mix[3], -1.0, 1.0);
  const Eigen::Vector4d q_yaw(std::cos(yaw_weight * std::acos(w_mix)), 0.0, 0.0,
                              std::sin(yaw_weight * std::asin(z_mix)));
  Eigen::Vector4d qe = quat_multiply(conjugate(q), quat_multiply(qd_red, q_yaw));
  if (qe[0] < 0) qe = -qe;
  Eigen::Vector3d w_sp;
  for (int i = 0; i < 3; ++i) w_sp[i] = 2.0 * qe[i + 1] * k[i];
  if (yaw_rate != 0.0) {  // world z in the body frame, times the yaw-rate feed-forward
    const Eigen::Vector3d z_W = world_z_in_body(q);
    for (int i = 0; i < 3; ++i) w_sp[i] += z_W[i] * yaw_rate;
  }
  for (int i = 0; i < 3; ++i) w_sp[i] = ra::py_min(ra::py_max(w_sp[i], -rate_max[i]), rate_max[i]);
  return w_sp;
}

}  // namespace cufund
