#include "position_control.h"

#include <cmath>

#include "geometric_control.h"
#include "reference_arithmetic.h"

namespace cufund {

namespace ra = reference_arithmetic;

PositionControl::PositionControl(double mass, double gravity, double max_thrust, double vel_d_cutoff_hz,
                                 double transfer_tau)
    : mass_(mass), gravity_(gravity), max_thrust_(max_thrust), acc_filter_(vel_d_cutoff_hz), handover_(transfer_tau) {}

void PositionControl::reset() {
  vel_int.setZero();
  acc_filter_.reset();
  handover_.reset();
}

const Eigen::Vector3d& PositionControl::filter_velocity(const Eigen::Vector3d& v_W, double dt) {
  return acc_filter_.update(v_W, dt);
}

Eigen::Vector3d PositionControl::limit_thrust(Eigen::Vector3d F, Eigen::Vector3i& sat) const {
  const PositionControlGains& g = gains_;
  sat.setZero();
  const double f_min = g.thr_min * max_thrust_, f_max = g.thr_max * max_thrust_;
  if (F[2] < f_min * std::cos(g.tilt_max)) {
    F[2] = f_min * std::cos(g.tilt_max);
    sat[2] = -1;
  }
  const double h = ra::hypot(F[0], F[1]);
  const double h_max = F[2] * std::tan(g.tilt_max);
  if (h > h_max) {
    const double s = h_max / h;
    F[0] *= s;
    F[1] *= s;
    sat[0] = ra::sign(F[0]);
    sat[1] = ra::sign(F[1]);
  }
  const double n = ra::norm<3>(F);
  if (n > f_max) {
    // keep the vertical component first (PX4 prioritises altitude), then what is left horizontally
    if (F[2] >= f_max) {
      F = Eigen::Vector3d(0.0, 0.0, f_max);
    } else {
      const double hh = std::sqrt(f_max * f_max - F[2] * F[2]);
      const double s = hh / ra::py_max(ra::hypot(F[0], F[1]), 1e-12);
      F[0] *= s;
      F[1] *= s;
      sat[0] = ra::sign(F[0]);
      sat[1] = ra::sign(F[1]);
    }
    sat[2] = 1;
  } else if (n < f_min) {
    F *= f_min / ra::py_max(n, 1e-12);
    sat[2] = -1;
  }
  return F;
}

PositionControlOutput PositionControl::step(double t, double dt, const Eigen::Vector3d& p_W, const Eigen::Vector3d& v_W,
                                            const Eigen::Vector3d& p_sp, const Eigen::Vector3d& v_sp_in,
                                            const Eigen::Vector3d& a_sp, double yaw, bool position_mode,
                                            const Eigen::Vector3d* handover) {
  const PositionControlGains& g = gains_;
  filter_velocity(v_W, dt);
  Eigen::Vector3d v_sp;
  for (int i = 0; i < 3; ++i) v_sp[i] = position_mode ? g.k_p[i] * (p_sp[i] - p_W[i]) + v_sp_in[i] : v_sp_in[i];
  const double vxy = ra::hypot(v_sp[0], v_sp[1]);
  if (vxy > g.xy_vel_max) {
    const double s = g.xy_vel_max / vxy;
    v_sp[0] *= s;
    v_sp[1] *= s;
  }
  v_sp[2] = ra::py_min(ra::py_max(v_sp[2], -g.z_vel_max_dn), g.z_vel_max_up);
  Eigen::Vector3d v_err, acc;
  for (int i = 0; i < 3; ++i) {
    v_err[i] = v_sp[i] - v_W[i];
    acc[i] = g.k_v[i] * v_err[i] + vel_int[i] - g.k_d[i] * acc_filter_.value[i] + a_sp[i];
  }
  handover_.apply(t, handover, acc);
  const Eigen::Vector3d up(0.0, 0.0, gravity_);
  Eigen::Vector3d F0;
  for (int i = 0; i < 3; ++i) F0[i] = mass_ * (acc[i] + up[i]);
  Eigen::Vector3i sat;
  const Eigen::Vector3d F = limit_thrust(F0, sat);
  // integrate unless the thrust vector saturated in the direction the error pushes (anti-windup)
  const double lim = gravity_;  // no more than 1 g from the integrator on any axis
  for (int i = 0; i < 3; ++i) {
    const double push = g.k_i[i] * v_err[i] * dt;
    const bool keep = !((sat[i] > 0 && push > 0) || (sat[i] < 0 && push < 0));
    vel_int[i] = ra::clamp(vel_int[i] + (keep ? push : 0.0), -lim, lim);
  }
  const double thrust = ra::norm<3>(F);
  const Eigen::Vector3d z_B(F[0] / thrust, F[1] / thrust, F[2] / thrust);
  return {rotation_to_quat(attitude_from_thrust_and_yaw(z_B, yaw)), thrust};
}

Eigen::Vector4d rotation_to_quat(const Eigen::Matrix3d& R) {
  const double tr = R(0, 0) + R(1, 1) + R(2, 2);
  Eigen::Vector4d q;
  if (tr > 0) {
    const double s = 2.0 * std::sqrt(tr + 1.0);
    q = Eigen::Vector4d(0.25 * s, (R(2, 1) - R(1, 2)) / s, (R(0, 2) - R(2, 0)) / s, (R(1, 0) - R(0, 1)) / s);
  } else if (R(0, 0) > R(1, 1) && R(0, 0) > R(2, 2)) {
    const double s = 2.0 * std::sqrt(1.0 + R(0, 0) - R(1, 1) - R(2, 2));
    q = Eigen::Vector4d((R(2, 1) - R(1, 2)) / s, 0.25 * s, (R(0, 1) + R(1, 0)) / s, (R(0, 2) + R(2, 0)) / s);
  } else if (R(1, 1) > R(2, 2)) {
    const double s = 2.0 * std::sqrt(1.0 + R(1, 1) - R(0, 0) - R(2, 2));
    q = Eigen::Vector4d((R(0, 2) - R(2, 0)) / s, (R(0, 1) + R(1, 0)) / s, 0.25 * s, (R(1, 2) + R(2, 1)) / s);
  } else {
    const double s = 2.0 * std::sqrt(1.0 + R(2, 2) - R(0, 0) - R(1, 1));
    q = Eigen::Vector4d((R(1, 0) - R(0, 1)) / s, (R(0, 2) + R(2, 0)) / s, (R(1, 2) + R(2, 1)) / s, 0.25 * s);
  }
  const double n = ra::norm<4>(q);
  for (int i = 0; i < 4; ++i) q[i] /= n;
  return q[0] >= 0 ? q : Eigen::Vector4d(-q);
}

}  // namespace cufund
