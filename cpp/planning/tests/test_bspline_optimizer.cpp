#include "bspline_optimizer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>

namespace cufund::planning {
namespace {

using Index = std::ptrdiff_t;

// A 6 x 4 x 3 m map at 0.1 m with a 0.6 m square pillar at x in [2.7, 3.3], y in [-0.3, 0.3] (origin y = -2).
std::unique_ptr<esdf::EsdfMap> pillar_map() {
  esdf::GridGeometry g;
  g.origin_W = {0.0, -2.0, 0.0};
  g.shape = {60, 40, 30};
  g.resolution = 0.1;
  auto m = std::make_unique<esdf::EsdfMap>(g, esdf::SensorModel{}, esdf::EsdfOptions{});
  std::vector<Index> occ;
  for (Index i = 27; i < 33; ++i)
    for (Index j = 17; j < 23; ++j)
      for (Index k = 0; k < 30; ++k) occ.push_back((i * 40 + j) * 30 + k);
  m->set_occupied(occ, std::vector<std::uint8_t>(occ.size(), 1));
  return m;
}

BsplineProblem problem() {
  BsplineProblem pb;
  pb.start = {{0.4, 0.01, 1.5}, {0.5, 0.01, 1.5}, {0.6, 0.01, 1.5}};
  pb.tail = {{5.5, 0.0, 1.5}, {5.5, 0.0, 1.5}, {5.5, 0.0, 1.5}};
  return pb;
}

std::vector<Vec3> straight(int n, double y = 0.01) {  // y = 0.01: through the pillar
  std::vector<Vec3> x;
  for (int i = 1; i <= n; ++i) x.push_back({0.6 + 4.9 * i / (n + 1), y, 1.5});
  return x;
}

TEST(BsplineOptimizer, GradientMatchesFiniteDifferences) {
  const auto map = pillar_map();
  BsplineWeights w;
  w.v_max = 1.0;  // make the feasibility terms active too
  w.a_max = 1.0;
  BsplineProblem pb = problem();
  pb.pull_end = true;
  pb.end_target = {5.0, 0.5, 1.4};
  std::mt19937_64 rng(3);
  std::normal_distribution<double> noise(0.0, 0.05);
  auto x = straight(20);
  for (auto& p : x)
    for (double& c : p) c += noise(rng);
  std::vector<Vec3> g;
  bspline_cost(*map, pb, w, x, &g);
  for (std::size_t i = 0; i < x.size(); ++i) {
    for (std::size_t a = 0; a < 3; ++a) {
      const double h = 1e-6;
      auto xp = x, xm = x;
      xp[i][a] += h;
      xm[i][a] -= h;
      const double fd = (bspline_cost(*map, pb, w, xp, nullptr) - bspline_cost(*map, pb, w, xm, nullptr)) / (2 * h);
      ASSERT_NEAR(g[i][a], fd, 1e-4 * std::max(1.0, std::fabs(fd))) << i << " " << a;
    }
  }
}

TEST(BsplineOptimizer, PushesControlPointsAwayFromThePillarAndIsDeterministic) {
  const auto map = pillar_map();
  BsplineWeights w;
  w.d_safe = 0.5;
  const auto pb = problem();
  // A guide grazing the pillar (0.1 m from its side), as a guide path planned with a small radius is.
  const auto x0 = straight(30, 0.4);
  const auto r = optimize_bspline(*map, pb, w, x0, LbfgsOptions{});
  EXPECT_LT(r.cost, bspline_cost(*map, pb, w, x0, nullptr) * 0.01);
  ClearanceMap cm(*map);
  double worst = 1e9;
  for (const auto& p : r.free) worst = std::min(worst, cm.clearance(p));
  EXPECT_GT(worst, 0.25);  // every control point clear of the pillar (the closest started 0.1 m from it)
  const auto again = optimize_bspline(*map, pb, w, x0, LbfgsOptions{});
  EXPECT_EQ(again.free, r.free);
  EXPECT_EQ(again.iterations, r.iterations);
}

}  // namespace
}  // namespace cufund::planning
