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

// Sparse sites in a large open grid: long lines carry many changed inputs at once, grown and shrunk
// on the same line, so updates combine several envelope segments with exact windows between them.
TEST(IncrementalEdt, BoxesAppearingAndVanishingInOpenSpaceEqualFullRecompute) {
  std::mt19937 rng(7);
  for (const std::array<Index, 3>& n : {std::array<Index, 3>{48, 41, 9}, std::array<Index, 3>{23, 64, 17}}) {
    const Index size = n[0] * n[1] * n[2];
    IncrementalEdt inc(n);
    inc.reset(test::random_sites(size, 0.0005, 3).data(), 2);
    for (int step = 0; step < 150; ++step) {
      std::vector<Index> idx;
      std::vector<std::uint8_t> val;
      // A few boxes set to sites or cleared, plus scattered single flips.
      for (int b = 0; b < 1 + step % 3; ++b) {
        std::array<Index, 3> lo{}, hi{};
        for (int a = 0; a < 3; ++a) {
          lo[a] = std::uniform_int_distribution<Index>(0, n[a] - 1)(rng);
          hi[a] = std::min(n[a] - 1, lo[a] + std::uniform_int_distribution<Index>(0, 4)(rng));
        }
        const std::uint8_t v = rng() % 2;
        for (Index x = lo[0]; x <= hi[0]; ++x)
          for (Index y = lo[1]; y <= hi[1]; ++y)
            for (Index z = lo[2]; z <= hi[2]; ++z) {
              idx.push_back((x * n[1] + y) * n[2] + z);
              val.push_back(v);
            }
      }
      for (int c = 0; c < 5; ++c) {
        idx.push_back(std::uniform_int_distribution<Index>(0, size - 1)(rng));
        val.push_back(rng() % 2);
      }
      const auto before = inc.squared_distance();
      const auto stats = inc.update(idx, val, step % 2 ? 1 : 2);
      IncrementalEdt full(n);
      full.reset(inc.sites().data(), 1);
      const auto after = inc.squared_distance();
      ASSERT_EQ(after, full.squared_distance()) << "step " << step;
      Index changed = 0;
      for (std::size_t i = 0; i < after.size(); ++i) changed += before[i] != after[i];
      EXPECT_EQ(stats.changed_distances, changed) << "step " << step;
      if (step % 50 == 0) {
        const auto ref = test::brute_squared(inc.sites(), n, {1.0, 1.0, 1.0});
        for (Index i = 0; i < size; ++i) {
          const std::int32_t got = after[static_cast<std::size_t>(i)];
          ASSERT_EQ(got == IncrementalEdt::kNoSite ? std::numeric_limits<double>::infinity() : got,
                    ref[static_cast<std::size_t>(i)]);
        }
      }
    }
  }
}

// Batches of one to a few hundred flips on small, flat or long grids (1-voxel axes included): updates
// switch back and forth between line windows and full passes.
TEST(IncrementalEdt, MidSizedBatchesOnSmallGridsEqualFullRecompute) {
  std::mt19937 rng(3);
  for (const std::array<Index, 3>& n :
       {std::array<Index, 3>{7, 1, 33}, std::array<Index, 3>{40, 3, 1}, std::array<Index, 3>{64, 64, 1},
        std::array<Index, 3>{90, 5, 4}, std::array<Index, 3>{30, 20, 10}}) {
    const Index size = n[0] * n[1] * n[2];
    IncrementalEdt inc(n);
    for (int step = 0; step < 60; ++step) {
      const int count = std::uniform_int_distribution<int>(1, 200)(rng);
      std::vector<Index> idx;
      std::vector<std::uint8_t> val;
      for (int c = 0; c < count; ++c) {
        idx.push_back(std::uniform_int_distribution<Index>(0, size - 1)(rng));
        val.push_back(rng() % 5 < 3 ? 1 : 0);
      }
      inc.update(idx, val, 2);
      IncrementalEdt full(n);
      full.reset(inc.sites().data(), 1);
      ASSERT_EQ(inc.squared_distance(), full.squared_distance()) << "step " << step;
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
