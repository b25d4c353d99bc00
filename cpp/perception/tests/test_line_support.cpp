// line_support against sets of bins counted one line at a time, on both of its paths (a few bins: a table of
// seen bins; bins spread wide: sorted lists).
#include <gtest/gtest.h>

#include <cstdint>
#include <memory>
#include <random>
#include <set>
#include <vector>

#include "line_support.h"

namespace cufund::perception {
namespace {

void check(std::int64_t spread, std::uint32_t seed) {
  std::mt19937 rng(seed);
  const std::size_t n = 300, k = 7;
  std::uniform_int_distribution<std::int64_t> bin(-spread, spread);
  std::bernoulli_distribution in(0.4);
  std::vector<std::int64_t> along(n * k);
  std::unique_ptr<bool[]> inlier(new bool[n * k]);
  for (std::size_t e = 0; e < n * k; ++e) {
    along[e] = bin(rng);
    inlier[e] = in(rng);
  }
  std::vector<std::int64_t> covered(k, -1), counts(k, -1);
  line_support(along.data(), inlier.get(), n, k, covered.data(), counts.data());
  for (std::size_t j = 0; j < k; ++j) {
    std::set<std::int64_t> bins;
    std::int64_t count = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (!inlier[i * k + j]) continue;
      bins.insert(along[i * k + j]);
      ++count;
    }
    EXPECT_EQ(covered[j], static_cast<std::int64_t>(bins.size())) << "line " << j;
    EXPECT_EQ(counts[j], count) << "line " << j;
  }
}

TEST(LineSupport, CountsDistinctBinsAndInliersWithFewBins) { check(40, 1); }

TEST(LineSupport, CountsDistinctBinsAndInliersWithBinsSpreadWide) { check(std::int64_t{1} << 40, 2); }

TEST(LineSupport, NoInliersNoSupport) {
  const std::int64_t along[4] = {1, 2, 3, 4};
  const bool inlier[4] = {false, false, false, false};
  std::int64_t covered[2] = {-1, -1}, counts[2] = {-1, -1};
  line_support(along, inlier, 2, 2, covered, counts);
  EXPECT_EQ(covered[0], 0);
  EXPECT_EQ(covered[1], 0);
  EXPECT_EQ(counts[0], 0);
  EXPECT_EQ(counts[1], 0);
}

}  // namespace
}  // namespace cufund::perception
