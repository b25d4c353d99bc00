#include "imu_propagation.h"

#include <cmath>

namespace cufund::odometry {

Eigen::Matrix3d skew(const Eigen::Vector3d& w) {
  Eigen::Matrix3d S;
  S << 0.0, -w.z(), w.y(), w.z(), 0.0, -w.x(), -w.y(), w.x(), 0.0;
  return S;
}

Eigen::Matrix3d so3_exp(const Eigen::Vector3d& w) {
  const double t2 = w.squaredNorm();
  const Eigen::Matrix3d W = skew(w);
  if (t2 < 1e-16) return Eigen::Matrix3d::Identity() + W + 0.5 * W * W;
  const double t = std::sqrt(t2);
  return Eigen::Matrix3d::Identity() + (std::sin(t) / t) * W + ((1.0 - std::cos(t)) / t2) * W * W;
}

namespace {

// Inverse of the right Jacobian of SO(3) at theta, applied to v.
Eigen::Vector3d apply_inv_right_jacobian(const Eigen::Vector3d& theta, const Eigen::Vector3d& v) {
  const double t2 = theta.squaredNorm();
  const Eigen::Vector3d wv = theta.cross(v);
  const Eigen::Vector3d wwv = theta.cross(wv);
  double c;
  if (t2 < 1e-10) {
    c = 1.0 / 12.0 + t2 / 720.0;
  } else {
    const double t = std::sqrt(t2);
    c = 1.0 / t2 - (1.0 + std::cos(t)) / (2.0 * t * std::sin(t));
  }
  return v + 0.5 * wv + c * wwv;
}

void write_state(const NavState& s, double* out) {
  const Eigen::Quaterniond q(s.R_WI);
  out[0] = s.p_W.x();
  out[1] = s.p_W.y();
  out[2] = s.p_W.z();
  out[3] = s.v_W.x();
  out[4] = s.v_W.y();
  out[5] = s.v_W.z();
  const double sign = q.w() < 0.0 ? -1.0 : 1.0;
  out[6] = sign * q.w();
  out[7] = sign * q.x();
  out[8] = sign * q.y();
  out[9] = sign * q.z();
}

}  // namespace

void propagate(const NavState& start, const Eigen::Vector3d& bias_acc, const Eigen::Vector3d& bias_gyr,
               const Eigen::Vector3d& gravity_W, const double* dt, const double* acc, const double* gyr, std::size_t n,
               double* states, double* rates) {
  Eigen::Vector3d theta = Eigen::Vector3d::Zero(), dP = Eigen::Vector3d::Zero(), dV = Eigen::Vector3d::Zero();
  double t = 0.0;
  write_state(start, states);
  for (std::size_t k = 0; k < n; ++k) {
    const double h = dt[k];
    const Eigen::Vector3d a = Eigen::Map<const Eigen::Vector3d>(acc + 3 * k) - bias_acc;
    const Eigen::Vector3d w = Eigen::Map<const Eigen::Vector3d>(gyr + 3 * k) - bias_gyr;
    const Eigen::Matrix3d dR = so3_exp(theta);
    const Eigen::Vector3d a_nav = dR * a;
    if (rates) {
      const Eigen::Vector3d a_W = start.R_WI * a_nav + gravity_W;
      for (int i = 0; i < 3; ++i) {
        rates[6 * k + i] = a_W[i];
        rates[6 * k + 3 + i] = w[i];
      }
    }
    dP += dV * h + a_nav * (0.5 * h * h);
    dV += a_nav * h;
    theta += apply_inv_right_jacobian(theta, w * h);
    t += h;
    NavState s;
    s.R_WI = start.R_WI * so3_exp(theta);
    s.p_W = start.p_W + start.v_W * t + 0.5 * gravity_W * t * t + start.R_WI * dP;
    s.v_W = start.v_W + gravity_W * t + start.R_WI * dV;
    write_state(s, states + 10 * (k + 1));
  }
}

}  // namespace cufund::odometry
