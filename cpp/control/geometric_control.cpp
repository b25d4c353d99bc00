#include "geometric_control.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace cufund {
namespace {

Eigen::Matrix3d rotation(const Eigen::Vector4d& q) {
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized().toRotationMatrix();
}

Eigen::Vector4d quaternion(const Eigen::Matrix3d& R) {
  Eigen::Quaterniond q(R);
  q.normalize();
  Eigen::Vector4d out(q.w(), q.x(), q.y(), q.z());
  return out[0] < 0 ? Eigen::Vector4d(-out) : out;
}

Eigen::Vector3d attitude_torque(const Eigen::Matrix3d& J, const Eigen::Vector3d& k_R, const Eigen::Vector3d& k_W,
                                const Eigen::Matrix3d& R, const Eigen::Vector3d& W, const Eigen::Matrix3d& R_d,
                                const Eigen::Vector3d& W_d) {
  const Eigen::Matrix3d RtRd = R.transpose() * R_d;
  const Eigen::Matrix3d E = RtRd.transpose() - RtRd;  // R_d^T R - R^T R_d
  const Eigen::Vector3d e_R = 0.5 * Eigen::Vector3d(E(2, 1), E(0, 2), E(1, 0));
  const Eigen::Vector3d W_d_B = RtRd * W_d;
  const Eigen::Vector3d e_W = W - W_d_B;
  return J * (-k_R.cwiseProduct(e_R) - k_W.cwiseProduct(e_W)) + W.cross(J * W) - J * W.cross(W_d_B);
}

}  // namespace

Eigen::Matrix3d attitude_from_thrust_and_yaw(const Eigen::Vector3d& z_B, double yaw) {
  const Eigen::Vector3d y_c(-std::sin(yaw), std::cos(yaw), 0.0);
  Eigen::Vector3d x_B = y_c.cross(z_B);
  double n = x_B.norm();
  if (n < 1e-6) {  // thrust horizontal along y_c: any x orthogonal to z
    x_B = std::abs(z_B.x()) < 0.9 ? Eigen::Vector3d(1, 0, 0) : Eigen::Vector3d(0, 0, 1);
    x_B -= x_B.dot(z_B) * z_B;
    n = x_B.norm();
  }
  x_B /= n;
  Eigen::Matrix3d R;
  R.col(0) = x_B;
  R.col(1) = z_B.cross(x_B);
  R.col(2) = z_B;
  return R;
}

GeometricAttitudeCommand geometric_from_force(const Eigen::Matrix3d& J, double mass, const Eigen::Vector3d& k_R,
                                              const Eigen::Vector3d& k_W, const Eigen::Vector4d& q_WB,
                                              const Eigen::Vector3d& w_B, const Eigen::Vector3d& F_W,
                                              const Eigen::Vector3d& j_W, double yaw, double yaw_rate) {
  const Eigen::Matrix3d R = rotation(q_WB);
  const double nF = F_W.norm();
  const Eigen::Vector3d b3 = nF > 1e-9 ? Eigen::Vector3d(F_W / nF) : Eigen::Vector3d(0, 0, 1);
  const Eigen::Matrix3d R_d = attitude_from_thrust_and_yaw(b3, yaw);
  Eigen::Vector3d W_d = Eigen::Vector3d::Zero();
  if (nF > 1e-9) {  // desired body rate from the jerk: h = m / |F| (j - (b3 . j) b3)
    const Eigen::Vector3d h = (mass / nF) * (j_W - b3.dot(j_W) * b3);
    W_d = Eigen::Vector3d(-h.dot(R_d.col(1)), h.dot(R_d.col(0)), yaw_rate * R_d(2, 2));
  }
  GeometricAttitudeCommand c;
  c.thrust = std::max(F_W.dot(R.col(2)), 0.0);
  c.torque_B = attitude_torque(J, k_R, k_W, R, w_B, R_d, W_d);
  c.q_WB_d = quaternion(R_d);
  return c;
}

GeometricAttitudeCommand geometric_from_attitude(const Eigen::Matrix3d& J, const Eigen::Vector3d& k_R,
                                                 const Eigen::Vector3d& k_W, const Eigen::Vector4d& q_WB,
                                                 const Eigen::Vector3d& w_B, const Eigen::Vector4d& q_WB_d,
                                                 double thrust, double yaw_rate) {
  const Eigen::Matrix3d R_d = rotation(q_WB_d);
  GeometricAttitudeCommand c;
  c.thrust = std::max(thrust, 0.0);
  c.torque_B = attitude_torque(J, k_R, k_W, rotation(q_WB), w_B, R_d, Eigen::Vector3d(0, 0, yaw_rate));
  c.q_WB_d = quaternion(R_d);
  return c;
}

GeometricControl::GeometricControl(const QuadrotorParams& params, double transfer_tau)
    : allocator_(params), J_(params.inertia), mass_(params.mass), gravity_(params.gravity), handover_(transfer_tau) {}

void GeometricControl::set_gains(double k_x, double k_v, const Eigen::Vector3d& k_R, const Eigen::Vector3d& k_W) {
  k_x_ = k_x;
  k_v_ = k_v;
  k_R_ = k_R;
  k_W_ = k_W;
}

GeometricStep GeometricControl::step_force(double t, const Eigen::Vector3d& p_W, const Eigen::Vector3d& v_W,
                                           const Eigen::Vector4d& q_WB, const Eigen::Vector3d& w_B,
                                           const Eigen::Vector3d& p_sp, const Eigen::Vector3d& v_sp,
                                           const Eigen::Vector3d& a_sp, const Eigen::Vector3d& j_sp, double yaw,
                                           double yaw_rate, bool position_mode, const Eigen::Vector3d* handover) {
  // element by element, in the order of the Python force law it replaces (same result bit for bit)
  Eigen::Vector3d F;
  for (int i = 0; i < 3; ++i) F[i] = mass_ * (a_sp[i] - k_v_ * (v_W[i] - v_sp[i]));
  F[2] += mass_ * gravity_;
  if (position_mode) {
    const double k = k_x_ * mass_;
    for (int i = 0; i < 3; ++i) F[i] -= k * (p_W[i] - p_sp[i]);
  }
  handover_.apply(t, handover, F);
  GeometricStep out;
  out.command = geometric_from_force(J_, mass_, k_R_, k_W_, q_WB, w_B, F, j_sp, yaw, yaw_rate);
  out.allocation = allocator_.allocate(out.command.thrust, out.command.torque_B);
  return out;
}

GeometricStep GeometricControl::step_attitude(const Eigen::Vector4d& q_WB, const Eigen::Vector3d& w_B,
                                              const Eigen::Vector4d& q_WB_d, double thrust, double yaw_rate) const {
  GeometricStep out;
  out.command = geometric_from_attitude(J_, k_R_, k_W_, q_WB, w_B, q_WB_d, thrust, yaw_rate);
  out.allocation = allocator_.allocate(out.command.thrust, out.command.torque_B);
  return out;
}

}  // namespace cufund
