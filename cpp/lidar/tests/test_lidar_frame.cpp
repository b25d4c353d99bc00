// The range model's realism terms (RangeModel past n_reflectivity) on hand-made cast frames: the formulas at
// points worked out by hand, and write_returns' mixed pixels, jitter and intensity noise ray by ray.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "lidar_frame.h"

namespace cufund::lidar {
namespace {

TEST(RangeModel, RangeSigmaGrowsWithRangeAndIncidenceAndStopsAt85Degrees) {
  RangeModel m;
  m.noise_std = 0.01;
  m.noise_per_m = 0.002;
  m.incidence_noise = 0.5;
  EXPECT_DOUBLE_EQ(range_sigma(m, 0.0, 1.0), 0.01);
  EXPECT_DOUBLE_EQ(range_sigma(m, 10.0, 1.0), 0.03);
  EXPECT_NEAR(range_sigma(m, 10.0, 0.5), 0.03 * 1.5, 1e-15);  // 60 deg: 1 / cos - 1 = 1
  const double at85 = 0.03 * (1.0 + 0.5 * (1.0 / std::cos(85.0 * M_PI / 180.0) - 1.0));
  EXPECT_NEAR(range_sigma(m, 10.0, std::cos(85.0 * M_PI / 180.0)), at85, 1e-12);
  EXPECT_NEAR(range_sigma(m, 10.0, 0.0), at85, 1e-12);  // grazing: capped, finite
  RangeModel off;
  off.noise_std = 0.02;
  EXPECT_EQ(range_sigma(off, 37.25, 0.0), 0.02);  // exactly the constant sigma when the new terms are off
}

TEST(RangeModel, DetectionProbabilityFallsFromOneToZeroPastTheDetectionRange) {
  RangeModel m;
  m.max_range_at_10pct = 40.0;
  m.detection_softness = 0.2;
  EXPECT_DOUBLE_EQ(detection_range(m, 0.1, 1.0), 40.0);
  EXPECT_DOUBLE_EQ(detection_range(m, 0.4, 1.0), 80.0);
  EXPECT_DOUBLE_EQ(detection_range(m, 0.4, 0.25), 40.0);
  EXPECT_EQ(detection_probability(m, 40.0, 0.1, 1.0), 1.0);
  EXPECT_DOUBLE_EQ(detection_probability(m, 44.0, 0.1, 1.0), 0.5);  // the middle of [40, 48]
  EXPECT_EQ(detection_probability(m, 48.0, 0.1, 1.0), 0.0);
  EXPECT_NEAR(detection_probability(m, 41.6, 0.1, 1.0), 1.0 - 0.2 * 0.2 * (3.0 - 0.4), 1e-12);
  double last = 1.0;  // monotone
  for (double r = 39.0; r < 50.0; r += 0.01) {
    const double p = detection_probability(m, r, 0.1, 1.0);
    EXPECT_LE(p, last);
    last = p;
  }
  EXPECT_EQ(detection_probability(m, 1.0, 0.0, 1.0), 0.0);  // black, or grazing: nothing past 0 m
  EXPECT_EQ(detection_probability(m, 1.0, 0.5, 0.0), 0.0);
  m.detection_softness = 0.0;  // a hard limit
  EXPECT_EQ(detection_probability(m, 40.0, 0.1, 1.0), 1.0);
  EXPECT_EQ(detection_probability(m, 40.001, 0.1, 1.0), 0.0);
  RangeModel off;
  EXPECT_EQ(detection_probability(off, 1e6, 0.01, 0.01), 1.0);
}

TEST(RangeModel, IntensitySigmaGrowsTowardsTheDetectionRange) {
  RangeModel m;
  m.intensity_noise = 0.1;
  EXPECT_EQ(intensity_sigma(m, 100.0, 0.1, 0.1), 0.1);  // no detection range: constant
  m.max_range_at_10pct = 20.0;
  EXPECT_DOUBLE_EQ(intensity_sigma(m, 0.0, 0.1, 1.0), 0.1);
  EXPECT_DOUBLE_EQ(intensity_sigma(m, 20.0, 0.1, 1.0), 0.2);
  EXPECT_DOUBLE_EQ(intensity_sigma(m, 20.0, 0.4, 1.0), 0.125);
}

// Six rays of one channel and one of another along +x, hitting walls at the given ranges (normal -x).
struct HandFrame {
  std::vector<double> d, t;
  std::vector<std::int32_t> ch;
  CastFrame cast;
  explicit HandFrame(const std::vector<double>& ranges, const std::vector<std::int32_t>& channels) {
    const std::size_t n = ranges.size();
    d.assign(3 * n, 0.0);
    t.resize(n);
    ch = channels;
    cast.rays.assign(6 * n, 0.0f);
    cast.normals.assign(3 * n, 0.0f);
    cast.geometry.assign(n, 0);
    cast.t_hit.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      d[3 * i] = 1.0;
      t[i] = 1e-3 * static_cast<double>(i);
      cast.rays[6 * i + 3] = 1.0f;
      cast.normals[3 * i] = -1.0f;
      cast.t_hit[i] = static_cast<float>(ranges[i]);
      cast.returns.push_back(static_cast<std::uint32_t>(i));
    }
    for (std::int32_t c = 0; c < 2; ++c) {  // by channel, then firing order
      for (std::size_t i = 0; i < n; ++i) {
        if (ch[i] == c) cast.order.push_back(static_cast<std::uint32_t>(i));
      }
    }
  }
  FrameRays rays() const { return {d.data(), t.data(), ch.data(), t.size()}; }
};

struct Out {
  std::vector<double> dt, ranges, intensity;
  std::vector<float> points_L, intensity_f32, points_W;
  std::vector<std::int32_t> channel;
  std::vector<std::uint32_t> ids;
  explicit Out(std::size_t m)
      : dt(m), ranges(m), intensity(m), points_L(3 * m), intensity_f32(m), points_W(3 * m), channel(m), ids(m) {}
  FrameReturns view() {
    return {dt.data(),      points_L.data(), ranges.data(), nullptr, intensity_f32.data(),
            channel.data(), points_W.data(), ids.data()};
  }
};

TEST(WriteReturns, MixedPixelsOnlyAtDepthEdgesOfTheirChannelAndBetweenTheSurfaces) {
  // Channel 0: 2, 2, 9 (edge), 9.1, inf (a miss: no edge), 9.2; channel 1 at 2 m between the far ones.
  const double inf = std::numeric_limits<double>::infinity();
  HandFrame f({2.0, 2.0, 9.0, 9.1, inf, 9.2, 2.0}, {0, 0, 0, 0, 0, 0, 1});
  f.cast.returns = {0, 1, 2, 3, 5, 6};
  RangeModel m;
  m.range_max = 100.0;
  m.mixed_probability = 0.5;
  m.mixed_edge = 0.3;
  std::vector<double> draw = {0.0, 0.5, 0.0, 0.25, 0.0, 0.75, 0.0, 0.5, 0.0, 0.5, 0.0, 0.5, 0.0, 0.5};
  m.mixed_draw = draw.data();
  Out out(f.cast.returns.size());
  write_returns(f.rays(), m, f.cast, out.view());
  EXPECT_EQ(out.ranges[0], 2.0);                             // no edge next to it
  EXPECT_DOUBLE_EQ(out.ranges[1], 2.0 + 0.25 * 7.0);         // the near side of the edge
  EXPECT_DOUBLE_EQ(out.ranges[2], 9.0 - 0.75 * 7.0);         // the far side
  EXPECT_FLOAT_EQ(static_cast<float>(out.ranges[3]), 9.1f);  // 0.1 m to its neighbour, a miss on the other side
  EXPECT_FLOAT_EQ(static_cast<float>(out.ranges[4]), 9.2f);  // next to the miss only
  EXPECT_EQ(out.ranges[5], 2.0);                             // alone in its channel
  EXPECT_FLOAT_EQ(out.points_L[3 * 1], static_cast<float>(2.0 + 0.25 * 7.0));
  EXPECT_FLOAT_EQ(out.points_W[3 * 1], 2.0f);  // the truth is the surface the ray hit
  draw[2] = 0.6;                               // above the probability: not mixed
  write_returns(f.rays(), m, f.cast, out.view());
  EXPECT_EQ(out.ranges[1], 2.0);
}

TEST(WriteReturns, JitterIsClampedAndIntensityNoiseIsRelative) {
  HandFrame f({5.0, 5.0, 5.0}, {0, 0, 0});
  RangeModel m;
  m.range_max = 100.0;
  std::vector<double> jitter = {-1.0, 0.5e-3, 1.0}, z = {1.0, -2.0, 0.0};
  m.dt_noise = jitter.data();
  m.dt_max = 0.1;
  m.intensity_z = z.data();
  m.intensity_noise = 0.1;
  Out out(3);
  write_returns(f.rays(), m, f.cast, out.view());
  EXPECT_EQ(out.dt[0], 0.0);
  EXPECT_DOUBLE_EQ(out.dt[1], 1.5e-3);
  EXPECT_EQ(out.dt[2], 0.1);
  EXPECT_FLOAT_EQ(out.intensity_f32[0], 1.0f);  // 1 x 1.1, clipped
  EXPECT_FLOAT_EQ(out.intensity_f32[1], 0.8f);
  EXPECT_FLOAT_EQ(out.intensity_f32[2], 1.0f);
}

}  // namespace
}  // namespace cufund::lidar
