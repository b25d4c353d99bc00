// Micro-benchmarks of cpp/esdf: full transform, incremental update, queries.
#include <benchmark/benchmark.h>

#include <cmath>
#include <random>
#include <vector>

#include "edt.h"
#include "esdf_map.h"

namespace cufund::esdf {
namespace {

std::vector<std::uint8_t> sparse_grid(std::array<std::ptrdiff_t, 3> n, double density) {
  std::mt19937 rng(1);
  std::bernoulli_distribution coin(density);
  std::vector<std::uint8_t> s(static_cast<std::size_t>(n[0] * n[1] * n[2]));
  for (auto& v : s) v = coin(rng);
  return s;
}

template <typename T>
void BM_Edt400x400x60(benchmark::State& state) {
  const std::array<std::ptrdiff_t, 3> n{400, 400, 60};
  const auto sites = sparse_grid(n, 0.01);
  std::vector<T> out(sites.size());
  EdtOptions opt;
  opt.voxel_size = {0.1, 0.1, 0.1};
  opt.nthreads = static_cast<int>(state.range(0));
  for (auto _ : state) {
    euclidean_distance_transform(sites.data(), n, opt, out.data());
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(sites.size()));
}
BENCHMARK(BM_Edt400x400x60<float>)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Edt400x400x60<double>)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_IncrementalSingleVoxel(benchmark::State& state) {
  const std::array<std::ptrdiff_t, 3> n{200, 200, 40};
  IncrementalEdt inc(n);
  inc.reset(sparse_grid(n, 0.002).data(), 2);
  const std::ptrdiff_t i = (100 * 200 + 100) * 40 + 20;
  std::uint8_t v = 1;
  for (auto _ : state) {
    benchmark::DoNotOptimize(inc.update({i}, {v}, 2));
    v ^= 1;
  }
}
BENCHMARK(BM_IncrementalSingleVoxel)->Unit(benchmark::kMicrosecond);

void BM_Query(benchmark::State& state) {
  GridGeometry g;
  g.shape = {200, 200, 40};
  g.resolution = 0.1;
  EsdfMap map(g, SensorModel{}, EsdfOptions{});
  std::vector<std::ptrdiff_t> idx;
  std::vector<std::uint8_t> val;
  const auto sites = sparse_grid(g.shape, 0.002);
  for (std::size_t i = 0; i < sites.size(); ++i) {
    if (sites[i]) {
      idx.push_back(static_cast<std::ptrdiff_t>(i));
      val.push_back(1);
    }
  }
  map.set_occupied(idx, val);
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const std::ptrdiff_t n = 100000;
  std::vector<double> p(3 * n), d(n), grad(3 * n);
  for (std::ptrdiff_t k = 0; k < n; ++k) {
    p[3 * k] = 20.0 * u(rng);
    p[3 * k + 1] = 20.0 * u(rng);
    p[3 * k + 2] = 4.0 * u(rng);
  }
  for (auto _ : state) {
    map.query(p.data(), n, d.data(), grad.data());
    benchmark::DoNotOptimize(d.data());
  }
  state.SetItemsProcessed(state.iterations() * n);
}
BENCHMARK(BM_Query)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace cufund::esdf

BENCHMARK_MAIN();
