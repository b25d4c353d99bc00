#include "quadrotor_params.h"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <sstream>

namespace cufund {
namespace {

bool finite(double x) { return std::isfinite(x); }

std::string expect(const char* field, const char* what, double got) {
  std::ostringstream os;
  os.precision(17);
  os << field << " must be " << what << ", got " << got;
  return os.str();
}

}  // namespace

std::string validate(const QuadrotorParams& p) {
  if (!(finite(p.mass) && p.mass > 0)) return expect("mass", "a finite number > 0 [kg]", p.mass);
  if (!p.inertia.allFinite()) return "inertia must be a finite 3x3 matrix [kg m^2], got non-finite entries";
  const double scale = p.inertia.cwiseAbs().maxCoeff();
  if (!((p.inertia - p.inertia.transpose()).cwiseAbs().maxCoeff() <= 1e-12 * scale)) {
    return "inertia must be symmetric [kg m^2], got an asymmetric matrix";
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(p.inertia);
  const Eigen::Vector3d ev = eig.eigenvalues();
  if (!(ev.minCoeff() > 0)) {
    return expect("inertia", "positive definite [kg m^2]; smallest eigenvalue", ev.minCoeff());
  }
  if (!(finite(p.arm_length) && p.arm_length > 0)) return expect("arm_length", "a finite number > 0 [m]", p.arm_length);
  // Plausibility: a rigid quadrotor's principal moments are within a few orders of magnitude of
  // m d^2 (about 0.3 m d^2 for a Crazyflie, 0.5 for an Iris). Far outside, the parameters are a typo
  // (e.g. inertia in g mm^2, or 1e-300) and the integration would overflow to NaN.
  const double md2 = p.mass * p.arm_length * p.arm_length;
  const double ratio_min = ev.minCoeff() / md2, ratio_max = ev.maxCoeff() / md2;
  if (!(ratio_min >= kInertiaRatioMin && ratio_max <= kInertiaRatioMax)) {
    std::ostringstream os;
    os.precision(3);
    os << "inertia must be plausible for the mass and arm_length: principal moments within [1e-6, 1e6] * mass * "
          "arm_length^2 = ["
       << kInertiaRatioMin * md2 << ", " << kInertiaRatioMax * md2 << "] kg m^2, got eigenvalues " << ev.minCoeff()
       << " to " << ev.maxCoeff() << " (units: kg m^2?)";
    return os.str();
  }
  if (!(finite(p.k_f) && p.k_f > 0)) return expect("k_f", "a finite number > 0 [N/(rad/s)^2]", p.k_f);
  if (!(finite(p.c_m) && p.c_m > 0)) return expect("c_m", "a finite number > 0 [m]", p.c_m);
  if (!(finite(p.tau_m) && p.tau_m > 0)) return expect("tau_m", "a finite number > 0 [s]", p.tau_m);
  if (!(finite(p.rotor_speed_min) && p.rotor_speed_min >= 0)) {
    return expect("rotor_speed_min", "a finite number >= 0 [rad/s]", p.rotor_speed_min);
  }
  if (!(finite(p.rotor_speed_max) && p.rotor_speed_max > p.rotor_speed_min)) {
    return expect("rotor_speed_max", "a finite number > rotor_speed_min [rad/s]", p.rotor_speed_max);
  }
  if (!(finite(p.rotor_drag_xy) && p.rotor_drag_xy >= 0)) {
    return expect("rotor_drag_xy", "a finite number >= 0 [kg/rad]", p.rotor_drag_xy);
  }
  if (!(finite(p.rotor_drag_z) && p.rotor_drag_z >= 0)) {
    return expect("rotor_drag_z", "a finite number >= 0 [kg/rad]", p.rotor_drag_z);
  }
  for (int i = 0; i < 3; ++i) {
    if (!(finite(p.body_drag(i)) && p.body_drag(i) >= 0)) {
      return expect("body_drag", "finite numbers >= 0 [N/(m/s)^2]", p.body_drag(i));
    }
  }
  if (!(finite(p.gravity) && p.gravity >= 0)) return expect("gravity", "a finite number >= 0 [m/s^2]", p.gravity);
  if (!(finite(p.max_integration_step) && p.max_integration_step > 0)) {
    return expect("max_integration_step", "a finite number > 0 [s]", p.max_integration_step);
  }
  if (!(p.ground_attitude.allFinite() && std::abs(p.ground_attitude.norm() - 1.0) <= 1e-6)) {
    return expect("ground_attitude", "a unit quaternion [w, x, y, z]; norm", p.ground_attitude.norm());
  }
  // a resting vehicle's z axis tilted at most 30 deg from vertical: 1 - 2 (x^2 + y^2) >= cos(30 deg)
  const Eigen::Vector4d& g = p.ground_attitude;
  if (!(1.0 - 2.0 * (g(1) * g(1) + g(2) * g(2)) >= 0.8660254037844386 /* cos(30 deg) */)) {
    return expect("ground_attitude", "a tilt of at most 30 deg from level; cos(tilt)",
                  1.0 - 2.0 * (g(1) * g(1) + g(2) * g(2)));
  }
  return "";
}

RotorGeometry rotor_geometry(const QuadrotorParams& p) {
  RotorGeometry g;
  const double d = p.arm_length;
  if (p.layout == RotorLayout::kPlus) {
    g.position_B = {Eigen::Vector3d(d, 0, 0), Eigen::Vector3d(0, -d, 0), Eigen::Vector3d(-d, 0, 0),
                    Eigen::Vector3d(0, d, 0)};
    g.spin = {-1.0, 1.0, -1.0, 1.0};
  } else {
    const double a = d / std::sqrt(2.0);
    g.position_B = {Eigen::Vector3d(a, -a, 0), Eigen::Vector3d(-a, a, 0), Eigen::Vector3d(a, a, 0),
                    Eigen::Vector3d(-a, -a, 0)};
    g.spin = {1.0, 1.0, -1.0, -1.0};
  }
  return g;
}

}  // namespace cufund
