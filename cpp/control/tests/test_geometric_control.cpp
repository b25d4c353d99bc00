#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "geometric_control.h"

namespace cufund {
namespace {

const Eigen::Matrix3d kJ = Eigen::Vector3d(0.0037, 0.0037, 0.0062).asDiagonal();
const Eigen::Vector3d kR(150, 150, 40), kW(22, 22, 10);

TEST(GeometricControl, HoverIsAnEquilibrium) {
  const double m = 0.8, g = 9.80665;
  const auto c = geometric_from_force(kJ, m, kR, kW, Eigen::Vector4d(1, 0, 0, 0), Eigen::Vector3d::Zero(),
                                      Eigen::Vector3d(0, 0, m * g), Eigen::Vector3d::Zero(), 0.0, 0.0);
  EXPECT_NEAR(c.thrust, m * g, 1e-12);
  EXPECT_LT(c.torque_B.norm(), 1e-15);
  EXPECT_LT((c.q_WB_d - Eigen::Vector4d(1, 0, 0, 0)).norm(), 1e-15);
}

TEST(GeometricControl, RestoringTorqueForRollError) {
  // rolled +0.3 rad about body x, desired level: torque about -x; thrust is the projection on body z
  const Eigen::Quaterniond q(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()));
  const auto c =
      geometric_from_force(kJ, 1.0, kR, kW, Eigen::Vector4d(q.w(), q.x(), q.y(), q.z()), Eigen::Vector3d::Zero(),
                           Eigen::Vector3d(0, 0, 10.0), Eigen::Vector3d::Zero(), 0.0, 0.0);
  EXPECT_NEAR(c.torque_B.x(), -kJ(0, 0) * kR.x() * std::sin(0.3), 1e-12);  // e_R = sin(angle) about x
  EXPECT_NEAR(c.torque_B.y(), 0.0, 1e-12);
  EXPECT_NEAR(c.thrust, 10.0 * std::cos(0.3), 1e-12);
}

TEST(GeometricControl, LargeErrorTorqueStillRestores) {
  // 150 deg about an axis in the xy plane: the torque points against the error axis
  const Eigen::Vector3d axis = Eigen::Vector3d(0.8, 0.6, 0).normalized();
  const Eigen::Quaterniond q(Eigen::AngleAxisd(150.0 * M_PI / 180.0, axis));
  const auto c = geometric_from_attitude(kJ, kR, kW, Eigen::Vector4d(q.w(), q.x(), q.y(), q.z()),
                                         Eigen::Vector3d::Zero(), Eigen::Vector4d(1, 0, 0, 0), 5.0, 0.0);
  EXPECT_LT(c.torque_B.normalized().dot(axis), -0.99);
  EXPECT_DOUBLE_EQ(c.thrust, 5.0);
}

TEST(GeometricControl, AttitudeFromThrustAndYawIsARotationWithThatHeading) {
  const Eigen::Vector3d z = Eigen::Vector3d(0.2, -0.1, 1.0).normalized();
  const Eigen::Matrix3d R = attitude_from_thrust_and_yaw(z, 0.7);
  EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), 1e-14);
  EXPECT_NEAR(R.determinant(), 1.0, 1e-14);
  EXPECT_LT((R.col(2) - z).norm(), 1e-15);
  EXPECT_NEAR(std::atan2(R(1, 0), R(0, 0)), 0.7, 0.05);  // heading close to yaw for a small tilt
  // PX4's construction: body x is orthogonal to the horizontal heading-left vector (-sin yaw, cos yaw, 0)
  EXPECT_NEAR(R.col(0).dot(Eigen::Vector3d(-std::sin(0.7), std::cos(0.7), 0.0)), 0.0, 1e-15);
}

}  // namespace
}  // namespace cufund
