// scan_rays against a motion with a closed form: constant velocity and constant yaw rate, for which
// linear position and slerp interpolation between knots are exact.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "scan_rays.h"

namespace cufund::lidar {
namespace {

TEST(ScanRays, ConstantVelocityAndYawRateAreInterpolatedExactly) {
  const double v[3] = {1.5, -0.5, 0.2}, rate = 2.0;  // [m/s], [rad/s]
  const std::size_t k = 5;
  std::vector<double> kt(k), kp(3 * k), kq(4 * k);
  for (std::size_t j = 0; j < k; ++j) {
    kt[j] = 10.0 + 0.025 * j;
    const double s = kt[j] - 10.0;
    for (int c = 0; c < 3; ++c) kp[3 * j + c] = v[c] * s;
    kq[4 * j] = std::cos(rate * s / 2);
    kq[4 * j + 3] = std::sin(rate * s / 2);
  }
  const std::size_t n = 101;
  std::vector<double> d(3 * n), t(n);
  std::vector<float> rays(6 * n);
  for (std::size_t i = 0; i < n; ++i) {
    t[i] = 10.0 + 0.1 * i / (n - 1);
    const double el = 0.3 * std::sin(0.7 * i), az = 0.13 * i;
    d[3 * i] = std::cos(el) * std::cos(az);
    d[3 * i + 1] = std::cos(el) * std::sin(az);
    d[3 * i + 2] = std::sin(el);
  }
  ASSERT_TRUE(scan_rays(d.data(), t.data(), n, kt.data(), kp.data(), kq.data(), k, rays.data()));
  for (std::size_t i = 0; i < n; ++i) {
    const double s = t[i] - 10.0, yaw = rate * s;
    const double* di = &d[3 * i];
    const float* r = &rays[6 * i];
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(r[c], v[c] * s, 1e-6) << i;
    EXPECT_NEAR(r[3], std::cos(yaw) * di[0] - std::sin(yaw) * di[1], 1e-6) << i;
    EXPECT_NEAR(r[4], std::sin(yaw) * di[0] + std::cos(yaw) * di[1], 1e-6) << i;
    EXPECT_NEAR(r[5], di[2], 1e-6) << i;
  }
}

TEST(ScanRays, TimesOutsideTheKnotsAreClampedAndOneKnotIsRejected) {
  const double kt[2] = {0.0, 1.0}, kp[6] = {0, 0, 0, 1, 2, 3}, kq[8] = {1, 0, 0, 0, 1, 0, 0, 0};
  const double d[3] = {0, 0, 1}, t[1] = {5.0};
  float r[6];
  ASSERT_TRUE(scan_rays(d, t, 1, kt, kp, kq, 2, r));
  EXPECT_FLOAT_EQ(r[0], 1.0f);
  EXPECT_FLOAT_EQ(r[2], 3.0f);
  EXPECT_FLOAT_EQ(r[5], 1.0f);
  EXPECT_FALSE(scan_rays(d, t, 1, kt, kp, kq, 1, r));
}

}  // namespace
}  // namespace cufund::lidar
