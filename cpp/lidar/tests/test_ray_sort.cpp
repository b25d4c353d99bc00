// Ray reordering: spatial_order and direction_tile_order return permutations, spatial_order's does
// not depend on the thread count and brings rays heading to the same place together.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

#include "ray_sort.h"

namespace cufund::lidar {
namespace {

std::vector<float> random_rays(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> o(-2.0f, 2.0f);
  std::normal_distribution<float> d(0.0f, 1.0f);
  std::vector<float> rays(6 * n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) rays[6 * i + k] = o(rng);
    for (int k = 3; k < 6; ++k) rays[6 * i + k] = d(rng);
  }
  return rays;
}

bool is_permutation_of_iota(std::vector<std::uint32_t> v) {
  std::sort(v.begin(), v.end());
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (v[i] != i) return false;
  }
  return true;
}

constexpr float kLo[3] = {-3.0f, -3.0f, -3.0f}, kHi[3] = {3.0f, 3.0f, 3.0f};

// Where ray i leaves the box [-3, 3]^3 (its origin is inside), computed independently in double.
std::array<double, 3> exit_point(const std::vector<float>& rays, std::uint32_t i) {
  const float* r = &rays[6 * i];
  double t = INFINITY;
  for (int k = 0; k < 3; ++k) {
    if (r[3 + k] != 0.0f) t = std::min(t, ((r[3 + k] > 0 ? 3.0 : -3.0) - r[k]) / r[3 + k]);
  }
  return {r[0] + t * r[3], r[1] + t * r[4], r[2] + t * r[5]};
}

// The point 3 m along ray i (half the box's side, kHeading's reach).
std::array<double, 3> heading_point(const std::vector<float>& rays, std::uint32_t i) {
  const float* r = &rays[6 * i];
  const double s = 3.0 / std::sqrt(double{r[3]} * r[3] + double{r[4]} * r[4] + double{r[5]} * r[5]);
  return {r[0] + s * r[3], r[1] + s * r[4], r[2] + s * r[5]};
}

// Mean distance between the key points of consecutive rays in the given order.
template <typename Point>
double mean_step(const std::vector<std::uint32_t>& order, const Point& point) {
  double sum = 0.0;
  for (std::size_t j = 1; j < order.size(); ++j) {
    const auto a = point(order[j - 1]), b = point(order[j]);
    sum += std::sqrt(std::pow(a[0] - b[0], 2) + std::pow(a[1] - b[1], 2) + std::pow(a[2] - b[2], 2));
  }
  return sum / static_cast<double>(order.size() - 1);
}

TEST(SpatialOrder, IsAPermutationIndependentOfThreadCount) {
  const std::size_t n = 150001;  // three blocks, the last one partial
  const auto rays = random_rays(n, 1);
  for (RayKey key : {RayKey::kHeading, RayKey::kBoxCrossing}) {
    std::vector<std::uint32_t> one(n), two(n), all(n);
    spatial_order(rays.data(), n, kLo, kHi, key, one.data(), 1);
    spatial_order(rays.data(), n, kLo, kHi, key, two.data(), 2);
    spatial_order(rays.data(), n, kLo, kHi, key, all.data(), 0);
    EXPECT_TRUE(is_permutation_of_iota(one));
    EXPECT_EQ(one, two);
    EXPECT_EQ(one, all);
  }
}

TEST(SpatialOrder, NeighboursMeetTheSamePart) {
  const std::size_t n = 100000;
  const auto rays = random_rays(n, 2);  // origins in [-2, 2]^3, inside the box
  std::vector<std::uint32_t> identity(n), heading(n), crossing(n);
  std::iota(identity.begin(), identity.end(), 0u);
  spatial_order(rays.data(), n, kLo, kHi, RayKey::kHeading, heading.data(), 2);
  spatial_order(rays.data(), n, kLo, kHi, RayKey::kBoxCrossing, crossing.data(), 2);
  auto along = [&](std::uint32_t i) { return heading_point(rays, i); };
  auto out = [&](std::uint32_t i) { return exit_point(rays, i); };
  // Random order: steps of about the size of the cloud of points (several m); sorted: a few cells
  // of about 10 m / 64.
  EXPECT_GT(mean_step(identity, along), 3.0);
  EXPECT_LT(mean_step(heading, along), 0.1 * mean_step(identity, along));
  EXPECT_GT(mean_step(identity, out), 3.0);
  EXPECT_LT(mean_step(crossing, out), 0.1 * mean_step(identity, out));
}

TEST(SpatialOrder, RaysFromOutsideKeyByWhereTheyEnter) {
  // Rays 0 and 1 start 10 m apart on the -x side and enter the box at almost the same point; rays
  // 2-4 start between them and point away, so they key by their origins. Keyed by origin, 0 and 1
  // would have the others between them; keyed by where they enter, they are neighbours.
  const std::vector<float> rays = {-10, 0, 0, 1,   0, 0, -20, 0.01f, 0, 1,   0, 0, -12, 0, 0,
                                   -1,  0, 0, -15, 0, 0, -1,  0,     0, -18, 0, 0, -1,  0, 0};
  std::vector<std::uint32_t> order(5);
  spatial_order(rays.data(), 5, kLo, kHi, RayKey::kBoxCrossing, order.data(), 1);
  EXPECT_TRUE(is_permutation_of_iota(order));
  const auto at = [&](std::uint32_t i) { return std::find(order.begin(), order.end(), i) - order.begin(); };
  EXPECT_EQ(at(1) - at(0), 1);
}

TEST(SpatialOrder, HandlesTinyAndDegenerateBatches) {
  std::vector<std::uint32_t> order(3, 99);
  spatial_order(nullptr, 0, kLo, kHi, RayKey::kHeading, order.data(), 2);
  EXPECT_EQ(order[0], 99u);
  // An empty scene (inverted box) and identical rays: one cell, input order kept.
  const float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  const std::vector<float> same = {1, 2, 3, 0, 0, 1, 1, 2, 3, 0, 0, 1, 1, 2, 3, 0, 0, 1};
  for (RayKey key : {RayKey::kHeading, RayKey::kBoxCrossing}) {
    spatial_order(same.data(), 3, lo, hi, key, order.data(), 2);
    EXPECT_EQ(order, (std::vector<std::uint32_t>{0, 1, 2}));
  }
}

TEST(DirectionTileOrder, IsAPermutationOfTheBatch) {
  const auto rays = random_rays(kMaxTileRays + 100, 3);
  std::vector<std::uint16_t> local(kMaxTileRays);
  direction_tile_order(rays.data(), 100, 100 + kMaxTileRays, local.data());
  EXPECT_TRUE(is_permutation_of_iota(std::vector<std::uint32_t>(local.begin(), local.end())));
}

}  // namespace
}  // namespace cufund::lidar
