// deskew_crop against poses written as yaw angles about z (R_WL = Rz(90 deg k) at knot k, the sensor moving along
// x): each point moved with the two knots around its time and blended, the crop box, and the tall columns.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "deskew_crop.h"

namespace cufund::perception {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr std::size_t kSegments = 2;
constexpr double kSpan = 1.0;

std::array<double, 3> sensor_at_knot(std::size_t k) { return {static_cast<double>(k), 0.0, 1.0}; }

std::array<double, 3> moved(const std::array<double, 3>& p, std::size_t k) {
  const double yaw = 0.5 * kPi * static_cast<double>(k);
  const auto t = sensor_at_knot(k);
  return {std::cos(yaw) * p[0] - std::sin(yaw) * p[1] + t[0], std::sin(yaw) * p[0] + std::cos(yaw) * p[1] + t[1],
          p[2] + t[2]};
}

// The point in the world and the sensor position at its firing time dt (clamped to [0, span]).
std::pair<std::array<double, 3>, std::array<double, 3>> expected(const std::array<double, 3>& p_L, double dt) {
  const double x = std::clamp(dt / kSpan, 0.0, 1.0) * kSegments;
  const std::size_t seg = std::min<std::size_t>(static_cast<std::size_t>(x), kSegments - 1);
  const double s = x - static_cast<double>(seg);
  const auto a = moved(p_L, seg), b = moved(p_L, seg + 1);
  const auto ta = sensor_at_knot(seg), tb = sensor_at_knot(seg + 1);
  std::array<double, 3> w{}, sensor{};
  for (int c = 0; c < 3; ++c) {
    w[c] = (1 - s) * a[c] + s * b[c];
    sensor[c] = (1 - s) * ta[c] + s * tb[c];
  }
  return {w, sensor};
}

std::int64_t column_key(double x, double y, double cell) {  // cufund.perception.detection.column_keys
  constexpr std::int64_t kOff = std::int64_t{1} << 30;
  return ((static_cast<std::int64_t>(std::floor(x / cell)) + kOff) << 31) |
         (static_cast<std::int64_t>(std::floor(y / cell)) + kOff);
}

struct Knots {
  std::vector<double> p, R;
  DeskewKnots view;
  Knots() {
    for (std::size_t k = 0; k <= kSegments; ++k) {
      const auto t = sensor_at_knot(k);
      p.insert(p.end(), t.begin(), t.end());
      const double yaw = 0.5 * kPi * static_cast<double>(k);
      R.insert(R.end(), {std::cos(yaw), -std::sin(yaw), 0.0, std::sin(yaw), std::cos(yaw), 0.0, 0.0, 0.0, 1.0});
    }
    view.segments = kSegments;
    view.span = kSpan;
    view.p_WL = p.data();
    view.R_WL = R.data();
  }
};

TEST(DeskewCrop, MovesEachPointWithTheBlendedPosesOfItsTimeAndCrops) {
  const Knots knots;
  const CropBox box{10.0, 0.5, 3.0, 2.5, 0.1};
  struct Row {
    std::array<float, 3> p_L;
    double dt;
  };
  const std::vector<Row> rows = {
      {{1.0f, 0.0f, 0.0f}, 0.25},    // kept: halfway between knots 0 and 1
      {{0.0f, 2.0f, 0.0f}, 0.5},     // kept: at knot 1
      {{1.0f, 0.0f, -0.8f}, 0.0},    // below z_min
      {{20.0f, 0.0f, 0.0f}, 0.0},    // beyond max_range
      {{0.0f, 0.0f, 1.6f}, 0.0},     // above tall_z: its column (0, 0) becomes tall
      {{0.05f, 0.05f, 0.0f}, 0.0},   // in that column: dropped with it
      {{3.0f, 3.0f, 0.0f}, 0.0},     // in a column already known tall
      {{0.5f, -1.0f, 0.25f}, 1.75},  // after the span: at the last knot
      {{-1.0f, 0.5f, 0.0f}, -0.5},   // before the start: at the first knot
  };
  std::vector<float> points;
  std::vector<double> dt;
  for (const auto& r : rows) {
    points.insert(points.end(), r.p_L.begin(), r.p_L.end());
    dt.push_back(r.dt);
  }
  const std::vector<std::int64_t> tall = {column_key(3.0, 3.0, 0.1)};
  CroppedScan out;
  deskew_crop(points.data(), dt.data(), rows.size(), 1, knots.view, box, tall.data(), tall.size(), out);

  const std::vector<std::size_t> kept = {0, 1, 7, 8};
  ASSERT_EQ(out.points_W.size(), 3 * kept.size());
  ASSERT_EQ(out.rays_W.size(), 3 * kept.size());
  for (std::size_t m = 0; m < kept.size(); ++m) {
    const Row& r = rows[kept[m]];
    const auto [w, sensor] = expected({r.p_L[0], r.p_L[1], r.p_L[2]}, r.dt);
    const double range = std::hypot(w[0] - sensor[0], w[1] - sensor[1], w[2] - sensor[2]);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(out.points_W[3 * m + c], w[c], 1e-12) << "row " << kept[m];
      EXPECT_NEAR(out.rays_W[3 * m + c], (w[c] - sensor[c]) / range, 1e-12) << "row " << kept[m];
    }
  }
  ASSERT_EQ(out.new_tall.size(), 1u);
  EXPECT_EQ(out.new_tall[0], column_key(0.0, 0.0, 0.1));

  // stride 2: rows 0, 2, 4, 6, 8 only (row 4 still makes its column tall; no row 5 to drop with it)
  deskew_crop(points.data(), dt.data(), rows.size(), 2, knots.view, box, tall.data(), tall.size(), out);
  ASSERT_EQ(out.points_W.size(), 3 * 2u);  // rows 0 and 8
  const auto [w8, s8] = expected({-1.0, 0.5, 0.0}, -0.5);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(out.points_W[3 + c], w8[c], 1e-12);
  EXPECT_EQ(out.new_tall, std::vector<std::int64_t>{column_key(0.0, 0.0, 0.1)});
}

}  // namespace
}  // namespace cufund::perception
