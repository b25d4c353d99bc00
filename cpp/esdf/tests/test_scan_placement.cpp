// place_frames against poses written as yaw angles: the body yaws 0 -> 90 deg about z and moves 0 -> 2 m along x
// over [0, 1] s, so at time t (both knots' weights equal at t = 0.5) it is at (2t, 0, 0) with yaw
// 2 atan2(s sin 45, (1 - s) + s cos 45) (the normalised linear blend of the two quaternions).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "scan_placement.h"

namespace cufund::esdf {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::array<double, 3> yawed(double yaw, const std::array<double, 3>& v) {
  return {std::cos(yaw) * v[0] - std::sin(yaw) * v[1], std::sin(yaw) * v[0] + std::cos(yaw) * v[1], v[2]};
}

double yaw_at(double t) { return 2 * std::atan2(t * std::sin(kPi / 4), (1 - t) + t * std::cos(kPi / 4)); }

TEST(PlaceFrames, EachFrameAtTheBodyPoseOfEachPointsTimeAndItsOriginAtTOrigin) {
  const double knot_t[2] = {0.0, 1.0};
  const double knot_p[6] = {0, 0, 0, 2, 0, 0};
  const double knot_q[8] = {1, 0, 0, 0, std::cos(kPi / 4), 0, 0, std::sin(kPi / 4)};
  const PoseKnots knots{knot_t, knot_p, knot_q, 2};
  RigidTransform T_BL;  // the LiDAR 0.1 m ahead of the body and 0.2 m up, upside down (180 deg about x)
  T_BL.R = {1, 0, 0, 0, -1, 0, 0, 0, -1};
  T_BL.t = {0.1, 0.0, 0.2};
  const std::vector<double> points_a = {1, 0, 0, 0, 1, 0, 0, 0, 1}, t_a = {0.0, 0.5, 1.0};
  const std::vector<double> points_b = {2, 3, 4}, t_b = {0.25};
  const LidarFrame frames[2] = {{points_a.data(), t_a.data(), 3, 0.5}, {points_b.data(), t_b.data(), 1, 2.0}};
  const auto placed = place_frames(knots, T_BL, frames, 2, 0);
  ASSERT_EQ(placed.size(), 2u);
  for (std::size_t f = 0; f < 2; ++f) {
    ASSERT_EQ(placed[f].points_W.size(), static_cast<std::size_t>(3 * frames[f].n));
    for (std::ptrdiff_t k = 0; k < frames[f].n; ++k) {
      const double t = frames[f].t[k];
      const double* p = frames[f].points_L + 3 * k;
      const std::array<double, 3> p_B = {p[0] + 0.1, -p[1], -p[2] + 0.2};
      const auto r = yawed(yaw_at(t), p_B);
      EXPECT_NEAR(placed[f].points_W[3 * k], 2 * t + r[0], 1e-12) << f << " " << k;
      EXPECT_NEAR(placed[f].points_W[3 * k + 1], r[1], 1e-12) << f << " " << k;
      EXPECT_NEAR(placed[f].points_W[3 * k + 2], r[2], 1e-12) << f << " " << k;
    }
    const double t0 = std::min(frames[f].t_origin, 1.0);  // clamped at the last knot
    const auto o = yawed(yaw_at(t0), {0.1, 0.0, 0.2});
    EXPECT_NEAR(placed[f].origin_W[0], 2 * t0 + o[0], 1e-12);
    EXPECT_NEAR(placed[f].origin_W[1], o[1], 1e-12);
    EXPECT_NEAR(placed[f].origin_W[2], o[2], 1e-12);
  }
  const auto one_thread = place_frames(knots, T_BL, frames, 2, 1);  // the same bit for bit
  for (std::size_t f = 0; f < 2; ++f) {
    EXPECT_EQ(one_thread[f].points_W, placed[f].points_W);
    EXPECT_EQ(one_thread[f].origin_W, placed[f].origin_W);
  }
}

}  // namespace
}  // namespace cufund::esdf
