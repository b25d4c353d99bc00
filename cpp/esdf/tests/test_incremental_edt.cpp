#include "incremental_edt.h"

#include <gtest/gtest.h>

#include <random>

#include "brute_force.h"

namespace cufund::esdf {
namespace {

using test::Index;

TEST(IncrementalEdt, RandomInsertRemoveSequencesEqualFullRecompute) {
  const std::array<Index, 3> n{13, 17, 11};
  const Index size = n[0] * n[1] * n[2];
  std::mt19937 rng(42);
  IncrementalEdt inc(n);
  inc.reset(test::random_sites(size, 0.01, 1).data(), 2);
  std::uniform_int_distribution<Index> voxel(0, size - 1);
  for (int step = 0; step < 60; ++step) {
    // Mostly small batches (a scan's worth of flips), sometimes large ones and clusters.
    const int count = step % 10 == 0 ? 300 : 1 + step % 7;
    std::vector<Index> idx;
    std::vector<std::uint8_t> val;
    for (int c = 0; c < count; ++c) {
      idx.push_back(voxel(rng));
      val.push_back(rng() % 3 == 0 ? 0 : (rng() % 2));
    }
    if (step % 5 == 0) {  // remove all sites in a block
      for (Index i = 0; i < size; i += 3) {
        idx.push_back(i);
        val.push_back(0);
      }
    }
    inc.update(idx, val, step % 2 ? 1 : 3);
    IncrementalEdt full(n);
    full.reset(inc.sites().data(), 1);
    ASSERT_EQ(inc.squared_distance(), full.squared_distance()) << "step " << step;
    const auto ref = test::brute_squared(inc.sites(), n, {1.0, 1.0, 1.0});
    const auto dist = inc.squared_distance();
    for (Index i = 0; i < size; ++i) {
      const std::int32_t got = dist[static_cast<std::size_t>(i)];
      const double want = ref[static_cast<std::size_t>(i)];
      ASSERT_EQ(got == IncrementalEdt::kNoSite ? std::numeric_limits<double>::infinity() : got, want);
    }
  }
}

TEST(IncrementalEdt, SingleInsertTouchesOnlyItsNeighbourhood) {
  const std::array<Index, 3> n{30, 30, 30};
  std::vector<std::uint8_t> sites(27000, 0);
  for (Index i = 0; i < 30; ++i)
    for (Index j = 0; j < 30; ++j) sites[static_cast<std::size_t>((i * 30 + j) * 30)] = 1;  // floor z = 0
  IncrementalEdt inc(n);
  inc.reset(sites.data(), 1);
  const auto before = inc.squared_distance();
  // A site at height 2 above the centre of the floor.
  const auto stats = inc.update({(15 * 30 + 15) * 30 + 2}, {1}, 1);
  EXPECT_EQ(stats.changed_sites, 1);
  EXPECT_EQ(stats.columns, 1);
  EXPECT_EQ(stats.y_lines, 28);  // stage 1 of that column changes at z = 2..29 (z^2 -> (z - 2)^2)
  const auto ref = test::brute_squared(inc.sites(), n, {1, 1, 1});
  const auto after = inc.squared_distance();
  Index changed = 0;
  for (std::size_t i = 0; i < ref.size(); ++i) {
    ASSERT_EQ(after[i], ref[i]);
    changed += before[i] != after[i];
  }
  EXPECT_EQ(stats.changed_distances, changed);
  EXPECT_LT(stats.x_lines, 30 * 30);  // not the whole grid
}

}  // namespace
}  // namespace cufund::esdf
