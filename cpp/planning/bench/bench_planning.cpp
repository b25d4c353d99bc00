#include <benchmark/benchmark.h>

#include <algorithm>
#include <memory>
#include <random>

#include "grid_astar.h"

namespace cufund::planning {
namespace {

using Index = std::ptrdiff_t;

// A 30 x 10 x 3 m forest of 0.2 m square trunks at 0.1 m resolution.
struct Forest {
  esdf::GridGeometry g;
  std::unique_ptr<esdf::EsdfMap> map;
  Forest() {
    g.shape = {300, 100, 30};
    g.resolution = 0.1;
    std::vector<Index> occ;
    std::mt19937_64 rng(1);
    std::uniform_int_distribution<Index> ui(20, 279), uj(0, 98);
    for (int t = 0; t < 45; ++t) {
      const Index i = ui(rng), j = uj(rng);
      for (Index di = 0; di < 2; ++di)
        for (Index dj = 0; dj < 2; ++dj)
          for (Index k = 0; k < 30; ++k) occ.push_back(((i + di) * 100 + j + dj) * 30 + k);
    }
    std::sort(occ.begin(), occ.end());
    occ.erase(std::unique(occ.begin(), occ.end()), occ.end());
    map = std::make_unique<esdf::EsdfMap>(g, esdf::SensorModel{}, esdf::EsdfOptions{});
    map->set_occupied(occ, std::vector<std::uint8_t>(occ.size(), 1));
  }
};

void BM_Clearance(benchmark::State& state) {
  static Forest f;
  ClearanceMap cm(*f.map);
  Vec3 p{5.03, 4.1, 1.5};
  for (auto _ : state) {
    p[0] += 1e-6;
    benchmark::DoNotOptimize(cm.clearance(p));
  }
}
BENCHMARK(BM_Clearance);

void BM_AStarForest(benchmark::State& state) {
  static Forest f;
  ClearanceMap cm(*f.map);
  GridAStar astar;
  AStarOptions opt;
  opt.radius = 0.25;
  for (auto _ : state) {
    benchmark::DoNotOptimize(astar.plan(cm, {0.5, 5.0, 1.5}, {29.5, 5.0, 1.5}, opt));
  }
}
BENCHMARK(BM_AStarForest)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace cufund::planning
BENCHMARK_MAIN();
