#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "quadrotor_params.h"
#include "test_helpers.h"

namespace cufund {
namespace {

TEST(QuadrotorParams, ValidParametersPass) { EXPECT_EQ(validate(testing::small_quad()), ""); }

TEST(QuadrotorParams, GroundAttitudeMustBeAUnitQuaternionWithinThirtyDegreesOfLevel) {
  QuadrotorParams p = testing::small_quad();
  p.ground_attitude = Eigen::Vector4d(std::cos(0.25), std::sin(0.25), 0.0, 0.0);  // 28.6 deg
  EXPECT_EQ(validate(p), "");
  p.ground_attitude = Eigen::Vector4d(std::cos(0.27), std::sin(0.27), 0.0, 0.0);  // 30.9 deg
  EXPECT_NE(validate(p).find("ground_attitude"), std::string::npos);
  p.ground_attitude = Eigen::Vector4d(2.0, 0.0, 0.0, 0.0);
  EXPECT_NE(validate(p).find("ground_attitude"), std::string::npos);
  p.ground_attitude = Eigen::Vector4d(std::numeric_limits<double>::quiet_NaN(), 0.0, 0.0, 0.0);
  EXPECT_NE(validate(p).find("ground_attitude"), std::string::npos);
}

TEST(QuadrotorParams, NonPositiveMassNamesField) {
  QuadrotorParams p = testing::small_quad();
  p.mass = -1.0;
  EXPECT_NE(validate(p).find("mass"), std::string::npos);
  p.mass = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(validate(p).find("mass"), std::string::npos);
}

TEST(QuadrotorParams, InertiaMustBeSymmetricPositiveDefinite) {
  QuadrotorParams p = testing::small_quad();
  p.inertia(0, 1) = 1e-6;  // asymmetric
  EXPECT_NE(validate(p).find("symmetric"), std::string::npos);
  p = testing::small_quad();
  p.inertia(2, 2) = -1e-5;
  EXPECT_NE(validate(p).find("positive definite"), std::string::npos);
  p = testing::small_quad();
  p.inertia(0, 1) = p.inertia(1, 0) = 2e-5;  // symmetric, indefinite (det < 0)
  EXPECT_NE(validate(p).find("positive definite"), std::string::npos);
}

TEST(QuadrotorParams, ImplausibleInertiaForTheMassIsRejected) {
  QuadrotorParams p = testing::small_quad();
  EXPECT_EQ(validate(p), "");
  p.inertia = Eigen::Matrix3d::Identity() * 1e-300;  // integrates to NaN in one step
  EXPECT_NE(validate(p).find("inertia must be plausible"), std::string::npos);
  p = testing::small_quad();
  p.mass = 1e-300;
  EXPECT_NE(validate(p).find("inertia must be plausible"), std::string::npos);
  p = testing::small_quad();
  p.inertia *= 1e9;  // kg mm^2 given as kg m^2
  EXPECT_NE(validate(p).find("inertia must be plausible"), std::string::npos);
}

TEST(QuadrotorParams, RotorLimitsOrdered) {
  QuadrotorParams p = testing::small_quad();
  p.rotor_speed_max = p.rotor_speed_min;
  EXPECT_NE(validate(p).find("rotor_speed_max"), std::string::npos);
}

TEST(QuadrotorParams, XLayoutFollowsPx4Numbering) {
  const RotorGeometry g = rotor_geometry(testing::small_quad());
  // 1 front-right, 2 rear-left, 3 front-left, 4 rear-right (FLU: +x front, +y left).
  EXPECT_GT(g.position_B[0].x(), 0);
  EXPECT_LT(g.position_B[0].y(), 0);
  EXPECT_LT(g.position_B[1].x(), 0);
  EXPECT_GT(g.position_B[1].y(), 0);
  EXPECT_GT(g.position_B[2].x(), 0);
  EXPECT_GT(g.position_B[2].y(), 0);
  EXPECT_LT(g.position_B[3].x(), 0);
  EXPECT_LT(g.position_B[3].y(), 0);
  for (const auto& r : g.position_B) EXPECT_NEAR(r.norm(), 0.043, 1e-15);
  EXPECT_EQ(g.spin[0], 1.0);
  EXPECT_EQ(g.spin[1], 1.0);
  EXPECT_EQ(g.spin[2], -1.0);
  EXPECT_EQ(g.spin[3], -1.0);
}

}  // namespace
}  // namespace cufund
