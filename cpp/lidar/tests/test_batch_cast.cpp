// batch_cast against RaycastScene::cast_rays on the same rays (bit for bit, every vehicle), the vehicle boxes
// against closed-form slab distances, the range model's rules, and bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "batch_cast.h"

namespace cufund::lidar {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// A floor z = 0 and a wall x = 4 (two big quads).
RaycastScene floor_and_wall() {
  RaycastScene s;
  const std::vector<float> floor = {-50, -50, 0, 50, -50, 0, 50, 50, 0, -50, 50, 0};
  const std::vector<float> wall = {4, -50, -50, 4, 50, -50, 4, 50, 50, 4, -50, 50};
  const std::vector<std::uint32_t> quad = {0, 1, 2, 0, 2, 3};
  s.add_triangles(floor.data(), 4, quad.data(), 2);
  s.add_triangles(wall.data(), 4, quad.data(), 2);
  return s;
}

std::vector<float> pinhole(int w, int h, double f) {
  std::vector<float> d;
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      d.push_back(1.0f);
      d.push_back(static_cast<float>(-(u + 0.5 - w / 2.0) / f));
      d.push_back(static_cast<float>(-(v + 0.5 - h / 2.0) / f));
    }
  return d;
}

TEST(BatchCast, EqualsCastRaysOfTheSameRaysBitForBit) {
  const RaycastScene scene = floor_and_wall();
  const std::vector<float> d = pinhole(24, 16, 12.0);
  const std::size_t r = d.size() / 3, n = 5;
  std::mt19937 gen(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> p, q;
  for (std::size_t i = 0; i < n; ++i) {
    p.insert(p.end(), {u(gen), u(gen), 1.5 + 0.5 * u(gen)});
    q.insert(q.end(), {1.0 + 0.2 * u(gen), 0.2 * u(gen), 0.2 * u(gen), 0.4 * u(gen)});  // normalised inside
  }
  const SensorPoses poses{p.data(), q.data(), n};
  std::vector<float> rays(6 * r * n), out(r * n), ref(r);
  ASSERT_EQ(batch_rays(poses, d.data(), r, rays.data()).status, BatchStatus::kOk);
  BatchRangeModel model;
  model.miss_value = kInf;
  ASSERT_EQ(batch_cast(scene, poses, d.data(), r, {}, model, out.data(), 2).status, BatchStatus::kOk);
  std::size_t hits = 0;
  for (std::size_t i = 0; i < n; ++i) {
    scene.cast_rays(rays.data() + 6 * r * i, r, RayHits{ref.data()}, 1, RayOrder::kCoherent);
    for (std::size_t k = 0; k < r; ++k) {
      ASSERT_EQ(out[r * i + k], ref[k]) << "vehicle " << i << " ray " << k;
      hits += std::isfinite(ref[k]) ? 1 : 0;
    }
  }
  EXPECT_GT(hits, n * r / 2);
}

TEST(BatchCast, DepthOfAWallIsItsDistanceAlongTheAxis) {
  const RaycastScene scene = floor_and_wall();
  const std::vector<float> d = pinhole(8, 8, 4.0);
  const double p[3] = {1.0, 0.0, 2.0}, q[4] = {1, 0, 0, 0};
  std::vector<float> out(64);
  BatchRangeModel model;
  model.range_max = 100.0f;
  batch_cast(scene, {p, q, 1}, d.data(), 64, {}, model, out.data());
  for (int v = 0; v < 4; ++v)  // the upper half sees the wall 3 m ahead
    for (int u = 0; u < 8; ++u) EXPECT_NEAR(out[8 * v + u], 3.0f, 1e-5f);
  model.range_max = 2.5f;  // beyond range_max: the miss value
  model.miss_value = -1.0f;
  batch_cast(scene, {p, q, 1}, d.data(), 64, {}, model, out.data());
  for (int u = 0; u < 8; ++u) EXPECT_EQ(out[u], -1.0f);
}

TEST(BatchCast, BoxDistanceIsTheSlabEntry) {
  const double c[3] = {5.0, 0.0, 0.0}, h[3] = {1.0, 2.0, 3.0}, id[4] = {1, 0, 0, 0};
  const double o[3] = {0.0, 0.0, 0.0}, dx[3] = {2.0, 0.0, 0.0}, up[3] = {0.0, 0.0, 1.0};
  EXPECT_DOUBLE_EQ(ray_box_distance(o, dx, c, id, h), 2.0);  // face x = 4 at t |d| = 4
  EXPECT_TRUE(std::isinf(ray_box_distance(o, up, c, id, h)));
  const double inside[3] = {5.0, 0.5, 0.5};
  EXPECT_EQ(ray_box_distance(inside, dx, c, id, h), 0.0);
  // yawed 90 deg: the box's x half extent now lies along world y, its y half extent (2) along world x
  const double yaw90[4] = {std::sqrt(0.5), 0.0, 0.0, std::sqrt(0.5)};
  EXPECT_NEAR(ray_box_distance(o, dx, c, yaw90, h), 1.5, 1e-12);
}

TEST(BatchCast, SensorsSeeOtherBoxesNotTheirOwn) {
  RaycastScene empty;
  const float d[3] = {1.0f, 0.0f, 0.0f};
  const double p[6] = {0, 0, 1, 3, 0, 1}, q[8] = {1, 0, 0, 0, 0, 0, 0, 1};  // facing each other
  const double h[6] = {0.1, 0.1, 0.05, 0.1, 0.1, 0.05};
  const std::int64_t owner[2] = {0, 1};
  const VehicleBoxes boxes{p, q, h, 2, owner};
  float out[2];
  BatchRangeModel model;
  model.miss_value = kInf;
  ASSERT_EQ(batch_cast(empty, {p, q, 2}, d, 1, boxes, model, out).status, BatchStatus::kOk);
  EXPECT_NEAR(out[0], 2.9f, 1e-6f);
  EXPECT_NEAR(out[1], 2.9f, 1e-6f);
  const std::int64_t nobody[2] = {-1, -1};  // without owners each sensor sits inside its own box
  ASSERT_EQ(batch_cast(empty, {p, q, 2}, d, 1, {p, q, h, 2, nobody}, model, out).status, BatchStatus::kOk);
  EXPECT_EQ(out[0], 0.0f);
}

TEST(BatchCast, BadInputIsNamedAndNothingIsWritten) {
  RaycastScene empty;
  const float d[6] = {1, 0, 0, 0, 0, 0};
  const double p[3] = {0, 0, 0}, q[4] = {1, 0, 0, 0}, q0[4] = {0, 0, 0, 0}, pn[3] = {NAN, 0, 0};
  float out[2] = {7.0f, 7.0f};
  BatchRangeModel model;
  BatchResult r = batch_cast(empty, {p, q, 1}, d, 2, {}, model, out);
  EXPECT_EQ(r.status, BatchStatus::kZeroDirection);
  EXPECT_EQ(r.index, 1u);
  EXPECT_EQ(batch_cast(empty, {p, q0, 1}, d, 1, {}, model, out).status, BatchStatus::kZeroQuaternion);
  EXPECT_EQ(batch_cast(empty, {pn, q, 1}, d, 1, {}, model, out).status, BatchStatus::kNonFinitePose);
  const double h[3] = {-1, 0, 0};
  EXPECT_EQ(batch_cast(empty, {p, q, 1}, d, 1, {p, q, h, 1, nullptr}, model, out).status, BatchStatus::kBadBox);
  EXPECT_EQ(out[0], 7.0f);
}

}  // namespace
}  // namespace cufund::lidar
