// Physical parameters of a quadrotor and their validation.
//
// Frames: world ENU (z up), body FLU (x forward, y left, z up), ROS REP 103.
// Units: SI throughout (kg, m, s, rad, N).
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>

namespace cufund {

constexpr int kNumRotors = 4;

// Rotor arrangement. Numbering follows PX4's airframe reference.
enum class RotorLayout {
  // "+": rotor 1 front (+x), 2 right (-y), 3 back (-x), 4 left (+y);
  // rotors 1 and 3 spin clockwise seen from above, 2 and 4 counter-clockwise (paper eq. 1).
  kPlus,
  // "x" (PX4 quad-x): rotor 1 front-right, 2 rear-left, 3 front-left, 4 rear-right;
  // rotors 1 and 2 spin counter-clockwise seen from above, 3 and 4 clockwise.
  kX,
};

struct QuadrotorParams {
  double mass = 1.0;                                      // [kg]
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Identity();  // J about the CoM, body FLU [kg m^2]
  double arm_length = 0.2;                                // d: CoM to rotor centre [m]
  RotorLayout layout = RotorLayout::kX;
  double k_f = 1e-5;                // rotor thrust f_i = k_f * omega_i^2 [N/(rad/s)^2]
  double c_m = 0.02;                // reaction torque per unit thrust (paper's c_M) [N m / N = m]
  double tau_m = 0.02;              // first-order motor time constant [s]
  double rotor_speed_min = 0.0;     // [rad/s]
  double rotor_speed_max = 1000.0;  // [rad/s]
  // Rotor drag ("H-force"), per rotor, linear in rotor speed and in the rotor's
  // air-relative velocity in the body frame: H_i = -omega_i * diag(kxy, kxy, kz) * v_air_i.
  double rotor_drag_xy = 0.0;  // [N/((rad/s)(m/s))] = [kg/rad]
  double rotor_drag_z = 0.0;   // [N/((rad/s)(m/s))] = [kg/rad]
  // Quadratic body (parasitic) drag on the body-frame air velocity:
  // D = -|v_air| * diag(c_d) * v_air.
  Eigen::Vector3d body_drag = Eigen::Vector3d::Zero();  // [N/(m/s)^2]
  double gravity = 9.80665;                             // [m/s^2]
  bool ground_plane = true;                             // rigid ground at z = 0
  double max_integration_step = 1e-3;                   // RK4 sub-step upper bound [s] (1 kHz default)
  // The attitude [w, x, y, z] a vehicle resting on the ground takes, its yaw kept: level (identity), or the
  // attitude of a tilted take-off pad (the landing gear follows the pad's slope).
  Eigen::Vector4d ground_attitude = Eigen::Vector4d(1.0, 0.0, 0.0, 0.0);
};

// Bounds on the principal moments of inertia over mass * arm_length^2 (a plausibility check).
constexpr double kInertiaRatioMin = 1e-6;
constexpr double kInertiaRatioMax = 1e6;

// Returns "" when the parameters are physical, else a message naming the field
// and what was expected, e.g. "mass must be a finite number > 0, got -1".
std::string validate(const QuadrotorParams& params);

// Rotor i position in body FLU [m] and spin sign s_i (+1 counter-clockwise seen
// from above, -1 clockwise). The reaction torque on the body is -s_i * c_m * f_i about +z.
struct RotorGeometry {
  std::array<Eigen::Vector3d, kNumRotors> position_B;
  std::array<double, kNumRotors> spin;
};
RotorGeometry rotor_geometry(const QuadrotorParams& params);

}  // namespace cufund
