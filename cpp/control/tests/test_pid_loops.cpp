// The PX4-style loops' C++ kernels against closed-form cases (tests/test_control_kernels.py holds them to the
// Python reference bit for bit on random inputs).
#include <gtest/gtest.h>

#include <cmath>

#include "attitude_control.h"
#include "position_control.h"
#include "rate_control.h"
#include "reference_arithmetic.h"

namespace cufund {
namespace {

QuadrotorParams vehicle() {  // cufund.presets.cu_astro()
  QuadrotorParams p;
  p.mass = 0.8;
  p.inertia = Eigen::Vector3d(0.0037118, 0.0037118, 0.0062208).asDiagonal();
  p.arm_length = 0.07 * std::sqrt(2.0);
  p.k_f = 4.97e-7;
  p.c_m = 0.0125;
  p.tau_m = 0.03;
  p.rotor_speed_max = 3140.0;
  return p;
}

PositionControlGains position_gains() {
  return {Eigen::Vector3d(3, 3, 3),
          Eigen::Vector3d(8, 8, 8),
          Eigen::Vector3d(2, 2, 2),
          Eigen::Vector3d(0.3, 0.3, 0),
          2.0,
          3.0,
          1.5,
          45.0 * M_PI / 180.0,
          0.12,
          1.0};
}

TEST(ReferenceArithmetic, HypotIsCorrectlyRoundedOnExactCases) {
  EXPECT_EQ(reference_arithmetic::hypot(3.0, 4.0), 5.0);
  EXPECT_EQ(reference_arithmetic::hypot(-5e-320, 0.0), 5e-320);  // subnormal path
  EXPECT_TRUE(std::isinf(reference_arithmetic::hypot(INFINITY, NAN)));
  EXPECT_TRUE(std::isnan(reference_arithmetic::hypot(1.0, NAN)));
  for (double x = 0.1; x < 100.0; x *= 1.37) {
    const double y = 0.7 * x + 0.3;
    EXPECT_NEAR(reference_arithmetic::hypot(x, y), std::hypot(x, y), 1e-15 * std::hypot(x, y));
  }
}

TEST(PositionControl, HoverAtTheSetpointCommandsWeightLevel) {
  const QuadrotorParams p = vehicle();
  PositionControl c(p.mass, p.gravity, 4.0 * p.k_f * p.rotor_speed_max * p.rotor_speed_max, 5.0, 0.2);
  c.set_gains(position_gains());
  const Eigen::Vector3d x(1.0, -2.0, 1.5), zero = Eigen::Vector3d::Zero();
  const double yaw = 0.4;
  const PositionControlOutput out = c.step(0.004, 0.004, x, zero, x, zero, zero, yaw, true, nullptr);
  EXPECT_NEAR(out.thrust, p.mass * p.gravity, 1e-12);
  EXPECT_NEAR(out.q_WB[0], std::cos(yaw / 2), 1e-12);
  EXPECT_NEAR(out.q_WB[3], std::sin(yaw / 2), 1e-12);
  EXPECT_NEAR(std::hypot(out.q_WB[1], out.q_WB[2]), 0.0, 1e-12);
  EXPECT_EQ(c.vel_int, zero);
}

TEST(PositionControl, TiltAndVelocityAreLimited) {
  const QuadrotorParams p = vehicle();
  const PositionControlGains g = position_gains();
  PositionControl c(p.mass, p.gravity, 4.0 * p.k_f * p.rotor_speed_max * p.rotor_speed_max, 5.0, 0.2);
  c.set_gains(g);
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  // 100 m away horizontally: the thrust vector leans by exactly the tilt limit
  const PositionControlOutput out =
      c.step(0.004, 0.004, zero, zero, Eigen::Vector3d(100, 0, 0), zero, zero, 0.0, true, nullptr);
  const double z_up = 1 - 2 * (out.q_WB[1] * out.q_WB[1] + out.q_WB[2] * out.q_WB[2]);
  EXPECT_NEAR(std::acos(z_up), g.tilt_max, 1e-9);
  EXPECT_GT(out.q_WB[2], 0.0);  // pitched towards +x (FLU: positive pitch tilts body z towards +x)
  // the integrator does not wind up in the saturated direction
  EXPECT_EQ(c.vel_int[0], 0.0);
}

TEST(AttitudeControl, RateSetpointIsZeroOnTargetAndProportionalForSmallRolls) {
  const Eigen::Vector3d k(10, 10, 10), rate_max(3.8, 3.8, 3.5);
  const Eigen::Vector4d q(std::cos(0.3), 0, 0, std::sin(0.3));
  EXPECT_EQ(attitude_rate_setpoint(q, q, 0.0, k, rate_max, 0.28), Eigen::Vector3d::Zero());
  const double roll = 0.01;
  const Eigen::Vector4d q_d = quat_multiply(q, Eigen::Vector4d(std::cos(roll / 2), std::sin(roll / 2), 0, 0));
  const Eigen::Vector3d w = attitude_rate_setpoint(q, q_d, 0.0, k, rate_max, 0.28);
  EXPECT_NEAR(w[0], 2 * k[0] * std::sin(roll / 2), 1e-12);
  EXPECT_NEAR(w[1], 0.0, 1e-12);
  EXPECT_NEAR(w[2], 0.0, 1e-12);
  // a large error saturates at the rate limit
  const Eigen::Vector4d q_far = quat_multiply(q, Eigen::Vector4d(std::cos(1.0), std::sin(1.0), 0, 0));
  EXPECT_EQ(attitude_rate_setpoint(q, q_far, 0.0, k, rate_max, 0.28)[0], rate_max[0]);
}

TEST(RateControl, NoErrorAtHoverGivesEqualRotorSpeeds) {
  const QuadrotorParams p = vehicle();
  RateControl c(p, 30.0, 400.0 * M_PI / 180.0);
  c.set_gains({Eigen::Vector3d(25, 25, 12), Eigen::Vector3d(10, 10, 5), Eigen::Vector3d(0.2, 0.2, 0), 0.0, 30.0});
  const Eigen::Vector3d w(0.1, -0.2, 0.05);
  const AllocationResult r = c.step(w, w, p.mass * p.gravity, 0.002);
  EXPECT_NEAR(r.achieved[0], p.mass * p.gravity, 1e-12);
  for (int i = 1; i < 4; ++i) EXPECT_NEAR(r.achieved[i], 0.0, 1e-15);
  const double hover = std::sqrt(p.mass * p.gravity / (4 * p.k_f));
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(r.rotor_speeds[i], hover, 1e-9 * hover);
  // a roll-rate error integrates: I grows by k_i e dt (1 - (e / 400 deg/s)^2)
  c.reset();
  c.step(Eigen::Vector3d::Zero(), Eigen::Vector3d(1.0, 0, 0), p.mass * p.gravity, 0.002);
  const double s = 1.0 / (400.0 * M_PI / 180.0);
  EXPECT_NEAR(c.rate_int[0], 10.0 * 1.0 * 0.002 * (1 - s * s), 1e-15);
}

}  // namespace
}  // namespace cufund
