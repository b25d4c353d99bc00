// Ray reordering: spatial_order and direction_tile_order return permutations, spatial_order's does
// not depend on the thread count and brings rays heading to the same place together.
#include <gtest/gtest.h>

#include <algorithm>
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

// Mean distance between the heading points of consecutive rays in the given order.
double mean_step(const std::vector<float>& rays, const std::vector<std::uint32_t>& order, float reach) {
  auto point = [&](std::uint32_t i, int k) {
    const float* r = &rays[6 * i];
    return r[k] + reach * r[3 + k] / std::sqrt(r[3] * r[3] + r[4] * r[4] + r[5] * r[5]);
  };
  double sum = 0.0;
  for (std::size_t j = 1; j < order.size(); ++j) {
    double d2 = 0.0;
    for (int k = 0; k < 3; ++k) d2 += std::pow(point(order[j], k) - point(order[j - 1], k), 2);
    sum += std::sqrt(d2);
  }
  return sum / static_cast<double>(order.size() - 1);
}

TEST(SpatialOrder, IsAPermutationIndependentOfThreadCount) {
  const std::size_t n = 150001;  // three blocks, the last one partial
  const auto rays = random_rays(n, 1);
  std::vector<std::uint32_t> one(n), two(n), all(n);
  spatial_order(rays.data(), n, 3.0f, one.data(), 1);
  spatial_order(rays.data(), n, 3.0f, two.data(), 2);
  spatial_order(rays.data(), n, 3.0f, all.data(), 0);
  EXPECT_TRUE(is_permutation_of_iota(one));
  EXPECT_EQ(one, two);
  EXPECT_EQ(one, all);
}

TEST(SpatialOrder, NeighboursHeadToTheSamePlace) {
  const std::size_t n = 100000;
  const auto rays = random_rays(n, 2);
  std::vector<std::uint32_t> identity(n), order(n);
  std::iota(identity.begin(), identity.end(), 0u);
  spatial_order(rays.data(), n, 3.0f, order.data(), 2);
  // Random order: steps of about the size of the cloud of heading points (~5 m); sorted: a few
  // cells of 10 m / 64.
  const double before = mean_step(rays, identity, 3.0f), after = mean_step(rays, order, 3.0f);
  EXPECT_GT(before, 3.0);
  EXPECT_LT(after, 0.1 * before);
}

TEST(SpatialOrder, HandlesTinyAndDegenerateBatches) {
  std::vector<std::uint32_t> order(3, 99);
  spatial_order(nullptr, 0, 1.0f, order.data(), 2);
  EXPECT_EQ(order[0], 99u);
  const std::vector<float> same = {1, 2, 3, 0, 0, 1, 1, 2, 3, 0, 0, 1, 1, 2, 3, 0, 0, 1};
  spatial_order(same.data(), 3, 0.0f, order.data(), 2);  // one point: input order kept
  EXPECT_EQ(order, (std::vector<std::uint32_t>{0, 1, 2}));
}

TEST(DirectionTileOrder, IsAPermutationOfTheBatch) {
  const auto rays = random_rays(kMaxTileRays + 100, 3);
  std::vector<std::uint16_t> local(kMaxTileRays);
  direction_tile_order(rays.data(), 100, 100 + kMaxTileRays, local.data());
  EXPECT_TRUE(is_permutation_of_iota(std::vector<std::uint32_t>(local.begin(), local.end())));
}

}  // namespace
}  // namespace cufund::lidar
