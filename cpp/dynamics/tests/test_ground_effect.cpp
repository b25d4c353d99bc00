#include <gtest/gtest.h>

#include <cmath>

#include "ground_effect.h"
#include "quadrotor_batch.h"
#include "test_helpers.h"

namespace cufund {
namespace {

using testing::run;
using testing::set_row;
using testing::small_quad;
using B = QuadrotorBatch;

GroundEffectParams cheeseman_bennett(double R) {
  GroundEffectParams g;
  g.enabled = true;
  g.rotor_radius = R;
  g.rotor_spacing = 1e6;  // the other rotors far away: one rotor alone
  g.min_height = 0.5 * R;
  g.ceiling_k1 = std::numeric_limits<double>::infinity();
  return g;
}

TEST(GroundEffect, SingleRotorIsCheesemanBennett) {
  const GroundEffectParams g = cheeseman_bennett(0.1);
  for (double z : {0.05, 0.1, 0.2, 0.5, 2.0}) {
    EXPECT_NEAR(ground_gain(g, z), 1.0 / (1.0 - std::pow(0.1 / (4 * z), 2)), 1e-14);
    EXPECT_EQ(ceiling_gain(g, z), 1.0);
  }
  EXPECT_EQ(ground_gain(g, 0.0), ground_gain(g, 0.05));  // clamped at min_height
  EXPECT_NEAR(ground_gain(g, std::numeric_limits<double>::infinity()), 1.0, 1e-14);
}

TEST(GroundEffect, ValidateNamesTheField) {
  GroundEffectParams g = cheeseman_bennett(0.1);
  EXPECT_EQ(validate(g), "");
  g.min_height = 0.0;
  EXPECT_NE(validate(g).find("min_height"), std::string::npos);
  g = cheeseman_bennett(0.1);
  g.min_height = 0.02;  // below R/4: past the singularity
  EXPECT_NE(validate(g).find("singularity"), std::string::npos);
  g = cheeseman_bennett(-1.0);
  EXPECT_NE(validate(g).find("rotor_radius"), std::string::npos);
}

// Hover near the ground: the rotor speed that balances the weight is the free-air one over sqrt(gain).
TEST(GroundEffect, HoverRotorSpeedFallsBySqrtOfGain) {
  QuadrotorParams p = small_quad();
  p.ground_plane = false;
  B b(p, 1);
  GroundEffectParams g = cheeseman_bennett(0.023);
  b.set_ground_effect(g);
  const double z = 0.03;  // rotor hubs lie in the body's x-y plane
  const double wh = b.hover_rotor_speed() / std::sqrt(ground_gain(g, z));
  set_row(b, B::kP, {0.0, 0.0, z});
  set_row(b, B::kRotor, {wh, wh, wh, wh});
  b.row(B::kFloorZ)[0] = 0.0;
  run(b, 1e-3, 1000, {wh, wh, wh, wh});
  EXPECT_NEAR(b.row(B::kP + 2)[0], z, 1e-9);
  EXPECT_NEAR(b.row(B::kAccel + 2)[0], 0.0, 1e-9);
}

TEST(QuadrotorBatch, EfficiencyAndSpeedLimitDefaultsAndReset) {
  QuadrotorParams p = small_quad();
  B b(p, 2);
  for (std::size_t i = 0; i < 2; ++i) {
    for (int k = 0; k < kNumRotors; ++k) EXPECT_EQ(b.row(B::kEta + k)[i], 1.0);
    EXPECT_EQ(b.row(B::kOmegaMax)[i], p.rotor_speed_max);
    EXPECT_EQ(b.row(B::kFloorZ)[i], 0.0);
    EXPECT_EQ(b.row(B::kCeilingZ)[i], std::numeric_limits<double>::infinity());
  }
  b.row(B::kEta + 2)[1] = 0.0;
  b.row(B::kOmegaMax)[0] = 10.0;
  b.reset();
  EXPECT_EQ(b.row(B::kEta + 2)[1], 1.0);
  EXPECT_EQ(b.row(B::kOmegaMax)[0], p.rotor_speed_max);
}

TEST(QuadrotorBatch, SpeedLimitClampsCommandPerVehicle) {
  QuadrotorParams p = small_quad();
  p.ground_plane = false;
  B b(p, 2);
  b.row(B::kOmegaMax)[1] = 1000.0;
  const std::vector<double> cmd(8, 2000.0);
  for (int k = 0; k < 100; ++k) b.step(1e-3, cmd.data(), 1);
  const double lag = 1 - std::exp(-0.1 / p.tau_m);
  EXPECT_NEAR(b.row(B::kRotor)[0], 2000.0 * lag, 1e-8 * 2000.0);
  EXPECT_NEAR(b.row(B::kRotor)[1], 1000.0 * lag, 1e-8 * 1000.0);
}

TEST(QuadrotorBatch, StoppedRotorLosesItsThrust) {
  QuadrotorParams p = small_quad();
  p.ground_plane = false;
  B b(p, 1);
  const double wh = b.hover_rotor_speed();
  set_row(b, B::kRotor, {wh, wh, wh, wh});
  for (int k = 0; k < kNumRotors; ++k) b.row(B::kEta + k)[0] = 0.75;
  run(b, 1e-9, 1, {wh, wh, wh, wh});
  EXPECT_NEAR(b.row(B::kAccel + 2)[0], -0.25 * p.gravity, 1e-9);
}

TEST(QuadrotorBatch, NonFiniteEfficiencyIsRefusedBeforeAStep) {
  B b(small_quad(), 1);
  b.row(B::kEta + 1)[0] = std::nan("");
  const std::vector<double> cmd(4, 0.0);
  const StepResult r = b.step(1e-3, cmd.data(), 1);
  EXPECT_EQ(r.status, StepStatus::kNonFiniteState);
  EXPECT_EQ(r.index, B::kEta + 1);
}

}  // namespace
}  // namespace cufund
