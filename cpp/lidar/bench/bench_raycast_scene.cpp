// Rays/s (wall clock, 2 threads) of RaycastScene on a UV sphere of about 10k / 100k / 1M triangles;
// second argument 0: random rays, 1: a 64-channel spinning scan from the centre, column by column.
// BM_SpatialOrder: the ray sort alone (second argument 0: RayKey::kHeading, 1: kBoxCrossing).
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "ray_sort.h"
#include "raycast_scene.h"

namespace {

using cufund::lidar::RaycastScene;
using cufund::lidar::RayHits;
using cufund::lidar::RayOrder;

// UV sphere of radius 3 around the origin with about `tris` triangles.
void add_sphere(RaycastScene& scene, int tris) {
  const int rings = std::max(4, static_cast<int>(std::sqrt(tris / 2.0)));
  const int segs = rings;
  std::vector<float> v;
  std::vector<std::uint32_t> t;
  for (int i = 0; i <= rings; ++i) {
    const double th = M_PI * i / rings;
    for (int j = 0; j < segs; ++j) {
      const double ph = 2 * M_PI * j / segs;
      v.push_back(static_cast<float>(3 * std::sin(th) * std::cos(ph)));
      v.push_back(static_cast<float>(3 * std::sin(th) * std::sin(ph)));
      v.push_back(static_cast<float>(3 * std::cos(th)));
    }
  }
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segs; ++j) {
      const std::uint32_t a = i * segs + j, b = i * segs + (j + 1) % segs, c = a + segs, d = b + segs;
      t.insert(t.end(), {a, c, b, b, c, d});
    }
  }
  scene.add_triangles(v.data(), v.size() / 3, t.data(), t.size() / 3);
}

void BM_CastRays(benchmark::State& state) {
  RaycastScene scene;
  add_sphere(scene, static_cast<int>(state.range(0)));
  const bool scan = state.range(1) != 0;
  const std::size_t n = 200000;
  std::vector<float> rays(6 * n);
  std::mt19937 rng(1);
  std::normal_distribution<float> g(0.0f, 1.0f);
  for (std::size_t i = 0; i < n; ++i) {
    float* r = &rays[6 * i];
    if (scan) {  // a spinning scan from the centre: azimuth fastest, 64 rings
      const double az = 2 * M_PI * (i % 3125) / 3125.0, el = -0.4 + 0.8 * (i / 3125) / 64.0;
      r[0] = r[1] = r[2] = 0.0f;
      r[3] = static_cast<float>(std::cos(el) * std::cos(az));
      r[4] = static_cast<float>(std::cos(el) * std::sin(az));
      r[5] = static_cast<float>(std::sin(el));
    } else {
      for (int k = 0; k < 6; ++k) r[k] = g(rng);
    }
  }
  std::vector<float> t(n), uv(2 * n), nrm(3 * n);
  std::vector<std::uint32_t> gid(n), pid(n);
  RayHits out{t.data(), gid.data(), pid.data(), uv.data(), nrm.data()};
  scene.cast_rays(rays.data(), 1, out, 1);  // builds the BVH outside the timed loop
  for (auto _ : state) {
    scene.cast_rays(rays.data(), n, out, 2, RayOrder::kAuto);
    benchmark::DoNotOptimize(t.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
}
BENCHMARK(BM_CastRays)->ArgsProduct({{10000, 100000, 1000000}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();

// Cost of ordering n random rays by heading (RayOrder::kSorted's overhead before any ray is cast).
void BM_SpatialOrder(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  std::vector<float> rays(6 * n);
  std::mt19937 rng(2);
  std::normal_distribution<float> g(0.0f, 1.0f);
  for (float& x : rays) x = g(rng);
  std::vector<std::uint32_t> order(n);
  const float lo[3] = {-3.0f, -3.0f, -3.0f}, hi[3] = {3.0f, 3.0f, 3.0f};
  const auto key = state.range(1) ? cufund::lidar::RayKey::kBoxCrossing : cufund::lidar::RayKey::kHeading;
  for (auto _ : state) {
    cufund::lidar::spatial_order(rays.data(), n, lo, hi, key, order.data(), 2);
    benchmark::DoNotOptimize(order.data());
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
}
BENCHMARK(BM_SpatialOrder)->ArgsProduct({{100000, 1000000}, {0, 1}})->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
