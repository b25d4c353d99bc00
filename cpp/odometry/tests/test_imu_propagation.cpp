// IMU propagation against closed-form motions the tangent-space scheme integrates exactly.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "imu_propagation.h"

namespace cufund::odometry {
namespace {

constexpr double kG = 9.81;

TEST(ImuPropagation, AtRestWithBiasesStaysPut) {
  const std::size_t n = 400;
  const Eigen::Vector3d ba(0.1, -0.2, 0.05), bg(0.01, 0.02, -0.03);
  std::vector<double> dt(n, 0.005), acc, gyr;
  for (std::size_t k = 0; k < n; ++k) {
    acc.insert(acc.end(), {ba.x(), ba.y(), kG + ba.z()});
    gyr.insert(gyr.end(), {bg.x(), bg.y(), bg.z()});
  }
  NavState s0;
  s0.p_W = Eigen::Vector3d(1, 2, 3);
  std::vector<double> states(10 * (n + 1));
  propagate(s0, ba, bg, Eigen::Vector3d(0, 0, -kG), dt.data(), acc.data(), gyr.data(), n, states.data(), nullptr);
  const double* last = states.data() + 10 * n;
  EXPECT_NEAR(last[0], 1.0, 1e-12);
  EXPECT_NEAR(last[2], 3.0, 1e-12);
  EXPECT_NEAR(last[5], 0.0, 1e-12);
  EXPECT_NEAR(last[6], 1.0, 1e-12);
}

TEST(ImuPropagation, YawAtConstantRateWhileCoastingIsExact) {
  // Rotation about z keeps gravity on the IMU's z axis, so a_W = 0: p = v0 t, R = Rz(w t).
  const std::size_t n = 300;
  const double w = 0.7, h = 0.004;
  std::vector<double> dt(n, h), acc, gyr, rates(6 * n);
  for (std::size_t k = 0; k < n; ++k) {
    acc.insert(acc.end(), {0.0, 0.0, kG});
    gyr.insert(gyr.end(), {0.0, 0.0, w});
  }
  NavState s0;
  s0.v_W = Eigen::Vector3d(0.5, -0.25, 0.1);
  std::vector<double> states(10 * (n + 1));
  propagate(s0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, -kG), dt.data(), acc.data(),
            gyr.data(), n, states.data(), rates.data());
  for (std::size_t k : {std::size_t{1}, n / 2, n}) {
    const double t = h * static_cast<double>(k);
    const double* s = states.data() + 10 * k;
    EXPECT_NEAR(s[0], 0.5 * t, 1e-12);
    EXPECT_NEAR(s[1], -0.25 * t, 1e-12);
    EXPECT_NEAR(s[2], 0.1 * t, 1e-12);
    EXPECT_NEAR(s[6], std::cos(0.5 * w * t), 1e-12);
    EXPECT_NEAR(s[9], std::sin(0.5 * w * t), 1e-12);
  }
  EXPECT_NEAR(rates[0], 0.0, 1e-12);
  EXPECT_NEAR(rates[2], 0.0, 1e-12);
  EXPECT_NEAR(rates[5], w, 1e-15);
}

TEST(ImuPropagation, ConstantThrustIsExactAndRotatedByTheStartAttitude) {
  // Start rolled 90 deg: IMU y points up; a specific force of g + 1 on y climbs at 1 m/s^2.
  const std::size_t n = 200;
  std::vector<double> dt(n, 0.005), acc, gyr(3 * n, 0.0);
  for (std::size_t k = 0; k < n; ++k) acc.insert(acc.end(), {0.0, kG + 1.0, 0.0});
  NavState s0;
  s0.R_WI = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  std::vector<double> states(10 * (n + 1));
  propagate(s0, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, -kG), dt.data(), acc.data(),
            gyr.data(), n, states.data(), nullptr);
  const double t = 1.0;
  EXPECT_NEAR(states[10 * n + 2], 0.5 * t * t, 1e-10);
  EXPECT_NEAR(states[10 * n + 5], t, 1e-10);
  EXPECT_NEAR(states[10 * n + 1], 0.0, 1e-10);
}

}  // namespace
}  // namespace cufund::odometry
