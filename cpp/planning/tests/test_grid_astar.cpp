#include "grid_astar.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>

namespace cufund::planning {
namespace {

using Index = std::ptrdiff_t;

// A 4 x 3 x 2 m box at 0.1 m with a wall at x in [1.5, 1.6] (voxel i = 15) and a square hole of
// `hole` voxels centred at y = 1.5, z = 1.0 (if hole > 0).
struct Wall {
  esdf::GridGeometry g;
  std::vector<Index> occ;
  std::unique_ptr<esdf::EsdfMap> map;
  explicit Wall(Index hole) {
    g.origin_W = {0.0, 0.0, 0.0};
    g.shape = {40, 30, 20};
    g.resolution = 0.1;
    for (Index j = 0; j < 30; ++j) {
      for (Index k = 0; k < 20; ++k) {
        const bool in_hole = hole > 0 && std::abs(2 * j + 1 - 30) < hole && std::abs(2 * k + 1 - 20) < hole;
        if (!in_hole) occ.push_back((15 * 30 + j) * 20 + k);
      }
    }
    map = std::make_unique<esdf::EsdfMap>(g, esdf::SensorModel{}, esdf::EsdfOptions{});
    map->set_occupied(occ, std::vector<std::uint8_t>(occ.size(), 1));
  }
  double distance(const Vec3& p) const {  // brute force to the occupied voxel cubes
    double best = std::numeric_limits<double>::infinity();
    for (Index i : occ) {
      const Index k = i % 20, j = (i / 20) % 30, ii = i / 600;
      const Index ijk[3] = {ii, j, k};
      double s = 0.0;
      for (std::size_t a = 0; a < 3; ++a) {
        const double lo = 0.1 * static_cast<double>(ijk[a]), hi = lo + 0.1;
        const double d = std::max({lo - p[a], 0.0, p[a] - hi});
        s += d * d;
      }
      best = std::min(best, std::sqrt(s));
    }
    return best;
  }
};

TEST(GridAStar, PassesThroughTheHoleWithClearanceAndIsDeterministic) {
  Wall w(8);  // 0.8 m hole: y in [1.1, 1.9], z in [0.6, 1.4]
  ClearanceMap cm(*w.map);
  GridAStar astar;
  AStarOptions opt;
  opt.radius = 0.2;
  const Vec3 start{0.5, 0.4, 0.5}, goal{3.5, 2.6, 1.5};
  const AStarResult a = astar.plan(cm, start, goal, opt);
  ASSERT_EQ(a.status, PathStatus::kFound);
  ASSERT_GE(a.path.size(), 3u);
  EXPECT_EQ(a.path.front(), start);
  EXPECT_EQ(a.path.back(), goal);
  bool crossed = false;
  for (std::size_t i = 1; i < a.path.size(); ++i) {
    for (int s = 0; s <= 200; ++s) {
      const double u = s / 200.0;
      const Vec3 p{a.path[i - 1][0] + u * (a.path[i][0] - a.path[i - 1][0]),
                   a.path[i - 1][1] + u * (a.path[i][1] - a.path[i - 1][1]),
                   a.path[i - 1][2] + u * (a.path[i][2] - a.path[i - 1][2])};
      ASSERT_GE(w.distance(p), opt.radius);
      if (std::fabs(p[0] - 1.55) < 0.01) {
        crossed = true;
        EXPECT_NEAR(p[1], 1.5, 0.2 + 1e-9);  // the hole leaves +-0.2 m for a 0.2 m radius
        EXPECT_NEAR(p[2], 1.0, 0.2 + 1e-9);
      }
    }
  }
  EXPECT_TRUE(crossed);
  // Shorter than going around anything, longer than the straight line.
  const double straight = std::sqrt(3.0 * 3.0 + 2.2 * 2.2 + 1.0 * 1.0);
  EXPECT_GE(a.length, straight);
  EXPECT_LE(a.length, 1.15 * straight);
  const AStarResult b = astar.plan(cm, start, goal, opt);  // buffers reused
  GridAStar fresh;
  const AStarResult c = fresh.plan(cm, start, goal, opt);
  EXPECT_EQ(a.path, b.path);
  EXPECT_EQ(a.path, c.path);
  EXPECT_EQ(a.expansions, c.expansions);
}

TEST(GridAStar, StatusWhenBlocked) {
  Wall sealed(0);
  ClearanceMap cm(*sealed.map);
  GridAStar astar;
  AStarOptions opt;
  opt.radius = 0.2;
  EXPECT_EQ(astar.plan(cm, {0.5, 0.4, 0.5}, {3.5, 2.6, 1.5}, opt).status, PathStatus::kNoPath);
  EXPECT_EQ(astar.plan(cm, {1.45, 0.4, 0.5}, {3.5, 2.6, 1.5}, opt).status, PathStatus::kStartBlocked);
  EXPECT_EQ(astar.plan(cm, {0.5, 0.4, 0.5}, {1.7, 2.6, 1.5}, opt).status, PathStatus::kGoalBlocked);
  EXPECT_EQ(astar.plan(cm, {0.5, 0.4, 0.5}, {9.0, 2.6, 1.5}, opt).status, PathStatus::kGoalBlocked);
  opt.max_expansions = 10;
  EXPECT_EQ(astar.plan(cm, {0.5, 0.4, 0.5}, {3.5, 2.6, 1.5}, opt).status, PathStatus::kExpansionLimit);
  Wall small(4);  // a 0.4 m hole cannot pass a 0.2 m radius (needs 0.4 + margins)
  ClearanceMap cs(*small.map);
  opt.max_expansions = 5000000;
  EXPECT_EQ(astar.plan(cs, {0.5, 0.4, 0.5}, {3.5, 2.6, 1.5}, opt).status, PathStatus::kNoPath);
  opt.radius = 0.05;
  EXPECT_EQ(astar.plan(cs, {0.5, 0.4, 0.5}, {3.5, 2.6, 1.5}, opt).status, PathStatus::kFound);
}

TEST(GridAStar, ShortcutKeepsEndsAndNeverLengthens) {
  Wall w(8);
  ClearanceMap cm(*w.map);
  GridAStar astar;
  AStarOptions opt;
  opt.radius = 0.2;
  opt.shortcut = false;
  const AStarResult raw = astar.plan(cm, {0.5, 0.4, 0.5}, {3.5, 2.6, 1.5}, opt);
  ASSERT_EQ(raw.status, PathStatus::kFound);
  const auto cut = shortcut_path(cm, raw.path, opt.radius);
  EXPECT_EQ(cut.front(), raw.path.front());
  EXPECT_EQ(cut.back(), raw.path.back());
  EXPECT_LT(cut.size(), raw.path.size());
  EXPECT_LE(path_length(cut), raw.length + 1e-12);
  for (std::size_t i = 1; i < cut.size(); ++i) EXPECT_TRUE(cm.segment_free(cut[i - 1], cut[i], opt.radius));
}

TEST(GridAStar, RelaxStraightensFreeZigZagAndKeepsClearanceThroughTheHole) {
  Wall w(8);
  ClearanceMap cm(*w.map);
  const double r = 0.2;
  // In front of the wall a zig-zag whose vertices no shortcut can drop in one jump becomes the straight line.
  const std::vector<Vec3> zig{{0.3, 0.3, 0.5}, {1.0, 1.0, 1.5}, {0.4, 1.6, 0.4}, {1.1, 2.2, 1.4}, {0.5, 2.7, 0.5}};
  const auto straight = relax_path(cm, zig, r);
  EXPECT_NEAR(path_length(straight), std::hypot(0.2, 2.4), 1e-9);
  // Through the hole: never longer than the shortcut path, ends kept, clear of the wall's cubes by the
  // radius (brute force every 5 mm), in the band, and bit-identical on a second run.
  GridAStar astar;
  AStarOptions opt;
  opt.radius = r;
  opt.shortcut = false;
  const AStarResult raw = astar.plan(cm, {0.5, 0.4, 0.5}, {3.5, 2.6, 1.5}, opt);
  ASSERT_EQ(raw.status, PathStatus::kFound);
  const auto cut = shortcut_path(cm, raw.path, r);
  const auto rel = relax_path(cm, cut, r, 0.3, 1.7);
  EXPECT_EQ(rel, relax_path(cm, cut, r, 0.3, 1.7));
  EXPECT_EQ(rel.front(), cut.front());
  EXPECT_EQ(rel.back(), cut.back());
  EXPECT_LE(path_length(rel), path_length(cut) + 1e-12);
  EXPECT_LT(path_length(rel), path_length(cut) - 1e-3);  // the voxel-centre corners are pulled tight
  for (std::size_t i = 1; i < rel.size(); ++i) {
    EXPECT_GE(rel[i][2], 0.3 - 1e-12);
    EXPECT_LE(rel[i][2], 1.7 + 1e-12);
    const Vec3 a = rel[i - 1], b = rel[i];
    const int n = static_cast<int>(std::ceil(std::hypot(b[0] - a[0], b[1] - a[1], b[2] - a[2]) / 0.005));
    for (int k = 0; k <= n; ++k) {
      const double u = static_cast<double>(k) / n;
      EXPECT_GE(w.distance({a[0] + u * (b[0] - a[0]), a[1] + u * (b[1] - a[1]), a[2] + u * (b[2] - a[2])}), r - 1e-9);
    }
  }
}

TEST(GridAStar, HeightBandExcludesVoxelsOutsideIt) {
  Wall w(8);  // hole z in [0.6, 1.4]: a band above it leaves no way through the wall
  ClearanceMap cm(*w.map);
  GridAStar astar;
  AStarOptions opt;
  opt.radius = 0.2;
  const Vec3 start{0.5, 1.5, 1.0}, goal{3.5, 1.5, 1.0};
  ASSERT_EQ(astar.plan(cm, start, goal, opt).status, PathStatus::kFound);
  opt.z_min = 0.75;  // voxel centres 0.75 .. 1.25 only: every node clears the hole's rim (z 0.6, 1.4) by 0.15
  opt.z_max = 1.25;
  opt.radius = 0.1;
  const AStarResult in_band = astar.plan(cm, start, goal, opt);
  ASSERT_EQ(in_band.status, PathStatus::kFound);
  for (std::size_t i = 1; i + 1 < in_band.path.size(); ++i) {
    EXPECT_GE(in_band.path[i][2], opt.z_min);
    EXPECT_LE(in_band.path[i][2], opt.z_max);
  }
  opt.z_min = 1.55;  // above the hole: the wall is closed there
  opt.z_max = 1.95;
  EXPECT_EQ(astar.plan(cm, {0.5, 1.5, 1.7}, {3.5, 1.5, 1.7}, opt).status, PathStatus::kNoPath);
}

}  // namespace
}  // namespace cufund::planning
