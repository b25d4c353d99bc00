#include "esdf_map.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "brute_force.h"

namespace cufund::esdf {
namespace {

using test::Index;

GridGeometry geometry(std::array<Index, 3> n, double res) {
  GridGeometry g;
  g.origin_W = {-1.0, -2.0, 0.0};
  g.shape = n;
  g.resolution = res;
  return g;
}

Index lin(const GridGeometry& g, Index i, Index j, Index k) { return (i * g.shape[1] + j) * g.shape[2] + k; }

TEST(OccupancyGrid, BeamMarksFreeAlongAndHitAtEnd) {
  const auto g = geometry({20, 10, 10}, 0.1);
  OccupancyGrid grid(g, SensorModel{});
  // Origin in voxel (2, 5, 5), end in voxel (15, 5, 5), along +x through voxel centres' row.
  const double o[3] = {-1.0 + 0.25, -2.0 + 0.55, 0.55};
  const double p[3 * 4] = {-1.0 + 1.55,  -2.0 + 0.55, 0.55,   // hit
                           std::nan(""), 0.0,         0.0,    // skipped
                           5.0,          -2.0 + 0.55, 0.55,   // outside: free to the border
                           -1.0 + 1.55,  -2.0 + 0.55, 0.55};  // same voxel again: one update
  std::vector<Index> flipped;
  std::vector<std::uint8_t> state;
  const ScanStats s = grid.insert_scan(p, 4, o, &flipped, &state);
  EXPECT_EQ(s.points, 4);
  EXPECT_EQ(s.nan_points, 1);
  EXPECT_EQ(s.outside, 1);
  EXPECT_EQ(s.hit_voxels, 1);
  EXPECT_EQ(s.free_voxels, 20 - 2 - 1);  // voxels 2..19 except the hit voxel 15
  const SensorModel m;
  EXPECT_EQ(grid.log_odds()[static_cast<std::size_t>(lin(g, 15, 5, 5))], m.log_odds_hit);
  for (Index i = 2; i < 20; ++i) {
    if (i == 15) continue;
    EXPECT_EQ(grid.log_odds()[static_cast<std::size_t>(lin(g, i, 5, 5))], m.log_odds_miss) << i;
  }
  EXPECT_EQ(grid.log_odds()[static_cast<std::size_t>(lin(g, 1, 5, 5))], 0.0f);
  EXPECT_EQ(grid.log_odds()[static_cast<std::size_t>(lin(g, 15, 6, 5))], 0.0f);
  ASSERT_EQ(flipped.size(), 1u);
  EXPECT_EQ(flipped[0], lin(g, 15, 5, 5));
  EXPECT_EQ(state[0], 1);
  // Clamping: many scans keep the log-odds within bounds.
  for (int r = 0; r < 20; ++r) grid.insert_scan(p, 1, o, &flipped, &state);
  EXPECT_EQ(grid.log_odds()[static_cast<std::size_t>(lin(g, 15, 5, 5))], m.log_odds_max);
  EXPECT_EQ(grid.log_odds()[static_cast<std::size_t>(lin(g, 10, 5, 5))], m.log_odds_min);
}

TEST(OccupancyGrid, MaxRangeCutsTheBeamWithoutHit) {
  const auto g = geometry({20, 10, 10}, 0.1);
  SensorModel model;
  model.max_range = 0.5;
  OccupancyGrid grid(g, model);
  const double o[3] = {-1.0 + 0.25, -2.0 + 0.55, 0.55};
  const double p[3] = {-1.0 + 1.55, -2.0 + 0.55, 0.55};
  std::vector<Index> flipped;
  std::vector<std::uint8_t> state;
  const ScanStats s = grid.insert_scan(p, 1, o, &flipped, &state);
  EXPECT_EQ(s.beyond_range, 1);
  EXPECT_EQ(s.hit_voxels, 0);
  EXPECT_EQ(s.free_voxels, 6);  // x from 0.25 to 0.75: voxels 2..7
  EXPECT_TRUE(flipped.empty());
}

std::vector<double> random_points(std::mt19937& rng, int n) {
  std::uniform_real_distribution<double> x(-1.5, 1.5), y(-2.5, 0.3), z(-0.3, 1.3);
  std::vector<double> pts;
  for (int k = 0; k < n; ++k) {
    pts.push_back(x(rng));
    pts.push_back(y(rng));
    pts.push_back(z(rng));
  }
  return pts;
}

TEST(OccupancyGrid, ScansInOneBatchGiveTheLogOddsOfScanByScanAndNetFlips) {
  const auto g = geometry({20, 20, 10}, 0.1);
  SensorModel model;
  model.max_range = 1.2;
  OccupancyGrid one(g, model), batch(g, model);
  std::mt19937 rng(3);
  std::vector<std::vector<double>> pts;
  std::vector<OccupancyGrid::Scan> scans;
  for (int k = 0; k < 23; ++k) pts.push_back(random_points(rng, 400));  // several groups of scans
  std::vector<Index> flipped;
  std::vector<std::uint8_t> state;
  for (int k = 0; k < 23; ++k) {
    const std::array<double, 3> o{-0.3 + 0.03 * k, -1.0, 0.5};
    one.insert_scan(pts[static_cast<std::size_t>(k)].data(), 400, o.data(), &flipped, &state, 1);
    scans.push_back({pts[static_cast<std::size_t>(k)].data(), 400, o});
  }
  std::vector<Index> net;
  std::vector<std::uint8_t> net_state;
  const ScanStats s = batch.insert_scans(scans, &net, &net_state, 2);
  EXPECT_EQ(s.points, 23 * 400);
  ASSERT_EQ(batch.log_odds().size(), one.log_odds().size());
  for (std::size_t i = 0; i < one.log_odds().size(); ++i) ASSERT_EQ(batch.log_odds()[i], one.log_odds()[i]) << i;
  // Every voxel started free: the net flips are exactly the occupied voxels, once each, ascending.
  std::vector<Index> occupied;
  for (Index i = 0; i < batch.size(); ++i) {
    if (batch.occupied(i)) occupied.push_back(i);
  }
  EXPECT_EQ(net, occupied);
  EXPECT_EQ(s.flipped_voxels, static_cast<Index>(occupied.size()));
  for (std::uint8_t v : net_state) EXPECT_EQ(v, 1);
}

TEST(OccupancyGrid, BeamsAlongFacesEdgesAndThroughCornersEndInTheirVoxelInsideTheGrid) {
  // Segments whose crossing times tie or overflow: along the grid's faces and edges, exactly through
  // voxel corners, sub-voxel and denormal extents. Each must hit its end voxel and free only voxels
  // between its start and end voxels (the walk takes exactly |end - start| steps per axis).
  const auto g = geometry({8, 8, 8}, 0.5);  // [-1, 3] x [-2, 2] x [0, 4]
  const double ends[][6] = {
      {-1.0, -2.0, 0.0, 3.0 - 1e-12, 2.0 - 1e-12, 4.0 - 1e-12},  // the main diagonal, corner to corner
      {-1.0, -2.0, 0.0, 2.99, -2.0, 0.0},                        // along an edge
      {0.0, 0.0, 1.0, 2.0, 2.0 - 1e-9, 3.0},                     // through voxel corners
      {0.1, 0.1, 0.1, 0.1 + 1e-300, 0.1, 2.9},                   // a denormal extent along x
      {0.2, 0.3, 0.4, 0.2000001, 0.3000001, 0.4000001},          // within one voxel
      {2.75, 1.75, 3.75, -0.75, -1.75, 0.25},                    // backwards along the diagonal of centres
  };
  for (const auto& e : ends) {
    OccupancyGrid grid(g, SensorModel{});
    std::vector<Index> flipped;
    std::vector<std::uint8_t> state;
    const ScanStats s = grid.insert_scan(e + 3, 1, e, &flipped, &state, 1);
    ASSERT_EQ(s.hit_voxels, 1);
    Index lo[3], hi[3], end[3];
    for (int a = 0; a < 3; ++a) {
      const auto v0 = static_cast<Index>(std::floor((e[a] - g.origin_W[a]) / g.resolution));
      end[a] = static_cast<Index>(std::floor((e[3 + a] - g.origin_W[a]) / g.resolution));
      lo[a] = std::min(v0, end[a]);
      hi[a] = std::max(v0, end[a]);
    }
    EXPECT_GT(grid.log_odds()[static_cast<std::size_t>(lin(g, end[0], end[1], end[2]))], 0.0f);
    Index free = 0;
    for (Index i = 0; i < grid.size(); ++i) {
      if (grid.log_odds()[static_cast<std::size_t>(i)] >= 0.0f) continue;
      ++free;
      const Index v[3] = {i / 64, (i / 8) % 8, i % 8};
      for (int a = 0; a < 3; ++a) EXPECT_TRUE(v[a] >= lo[a] && v[a] <= hi[a]) << i;
    }
    EXPECT_EQ(free, s.free_voxels);
    EXPECT_LE(free, (hi[0] - lo[0]) + (hi[1] - lo[1]) + (hi[2] - lo[2]));
  }
}

TEST(OccupancyGrid, MergedBeamsHitTheSameVoxelsAndFreeASubset) {
  const auto g = geometry({30, 30, 12}, 0.1);
  SensorModel model;
  model.max_range = 1.5;
  SensorModel merged_model = model;
  merged_model.merge_beams = true;
  std::mt19937 rng(11);
  for (int scan = 0; scan < 4; ++scan) {
    OccupancyGrid every(g, model), merged(g, merged_model);
    const auto pts = random_points(rng, 5000);  // many points per voxel
    const double o[3] = {0.1 * scan, -1.0, 0.6};
    std::vector<Index> flipped;
    std::vector<std::uint8_t> state;
    const ScanStats a = every.insert_scan(pts.data(), 5000, o, &flipped, &state, 1);
    const ScanStats b = merged.insert_scan(pts.data(), 5000, o, &flipped, &state, 2);
    EXPECT_EQ(a.hit_voxels, b.hit_voxels);
    EXPECT_LT(b.beams, a.beams);
    EXPECT_LE(b.free_voxels, a.free_voxels);
    for (Index i = 0; i < every.size(); ++i) {
      const float la = every.log_odds()[static_cast<std::size_t>(i)],
                  lb = merged.log_odds()[static_cast<std::size_t>(i)];
      ASSERT_EQ(la > 0.0f, lb > 0.0f) << i;       // the same hits
      ASSERT_TRUE(lb >= 0.0f || la < 0.0f) << i;  // freed by a merged beam: freed by some beam
    }
  }
}

TEST(EsdfMap, RandomScansKeepTheFieldEqualToARecompute) {
  const auto g = geometry({24, 20, 12}, 0.2);
  EsdfMap map(g, SensorModel{}, EsdfOptions{});
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> x(-1.5, 4.3), y(-2.5, 2.3), z(-0.3, 2.6);
  for (int scan = 0; scan < 25; ++scan) {
    const double o[3] = {1.0 + 0.05 * scan, 0.0, 1.0};
    std::vector<double> pts;
    for (int k = 0; k < 200; ++k) {
      pts.push_back(x(rng));
      pts.push_back(y(rng));
      pts.push_back(z(rng));
    }
    map.insert_scan(pts.data(), 200, o);
    const auto outside = map.outside_squared(), inside = map.inside_squared();
    EsdfMap copy = map;  // recompute a copy from its occupancy
    copy.recompute();
    ASSERT_EQ(copy.outside_squared(), outside) << "scan " << scan;
    ASSERT_EQ(copy.inside_squared(), inside) << "scan " << scan;
  }
  // And the field is the brute-force one.
  std::vector<std::uint8_t> occ(static_cast<std::size_t>(map.occupancy().size()));
  for (Index i = 0; i < map.occupancy().size(); ++i) occ[static_cast<std::size_t>(i)] = map.occupancy().occupied(i);
  const auto ref = test::brute_squared(occ, g.shape, {1, 1, 1});
  for (std::size_t i = 0; i < ref.size(); ++i) {
    if (!occ[i]) {
      ASSERT_DOUBLE_EQ(map.voxel_distance(static_cast<Index>(i)), std::sqrt(ref[i]) * 0.2);
    } else {
      ASSERT_LT(map.voxel_distance(static_cast<Index>(i)), 0.0);
    }
  }
}

TEST(EsdfMap, QueryInterpolatesVoxelCentresAndGradientMatchesFiniteDifferences) {
  const auto g = geometry({16, 14, 12}, 0.25);
  EsdfMap map(g, SensorModel{}, EsdfOptions{});
  map.set_occupied({lin(g, 5, 6, 4), lin(g, 11, 3, 9), lin(g, 6, 6, 4)}, {1, 1, 1});
  // At voxel centres the query returns the voxel distances.
  for (Index i : {Index{0}, lin(g, 5, 6, 4), lin(g, 7, 7, 7), lin(g, 15, 13, 11)}) {
    const Index ix = i / (14 * 12), iy = (i / 12) % 14, iz = i % 12;
    const double p[3] = {-1.0 + 0.25 * (ix + 0.5), -2.0 + 0.25 * (iy + 0.5), 0.25 * (iz + 0.5)};
    double d;
    map.query(p, 1, &d, nullptr);
    EXPECT_DOUBLE_EQ(d, map.voxel_distance(i));
  }
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> x(-0.8, 2.8), y(-1.8, 1.3), z(0.2, 2.8);
  for (int k = 0; k < 200; ++k) {
    const double p[3] = {x(rng), y(rng), z(rng)};
    double d, grad[3];
    map.query(p, 1, &d, grad);
    for (int a = 0; a < 3; ++a) {
      const double eps = 1e-6;
      double pp[3] = {p[0], p[1], p[2]}, pm[3] = {p[0], p[1], p[2]};
      pp[a] += eps;
      pm[a] -= eps;
      double dp, dm;
      map.query(pp, 1, &dp, nullptr);
      map.query(pm, 1, &dm, nullptr);
      ASSERT_NEAR(grad[a], (dp - dm) / (2 * eps), 1e-6) << "axis " << a;
    }
  }
  const double bad[3] = {std::nan(""), 0.0, 0.0};
  double d, grad[3];
  map.query(bad, 1, &d, grad);
  EXPECT_TRUE(std::isnan(d));
}

}  // namespace
}  // namespace cufund::esdf
