// Micro-benchmarks of the LIO kernels on a synthetic 12 m x 8 m x 4 m room (Mid-360-like frame sizes).
#include <benchmark/benchmark.h>

#include <random>
#include <vector>

#include "deskew.h"
#include "imu_propagation.h"
#include "voxel_map.h"

namespace cufund::odometry {
namespace {

std::vector<double> room_points(std::size_t n, double noise, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, noise);
  std::vector<double> pts;
  pts.reserve(3 * n);
  const double L[3] = {12.0, 8.0, 4.0};
  for (std::size_t i = 0; i < n; ++i) {
    const int face = static_cast<int>(i % 6), axis = face / 2;
    double p[3] = {u(rng) * L[0] - 6.0, u(rng) * L[1] - 4.0, u(rng) * L[2]};
    p[axis] = face % 2 ? (axis == 2 ? L[2] : L[axis] / 2) : (axis == 2 ? 0.0 : -L[axis] / 2);
    for (double& c : p) c += g(rng);
    pts.insert(pts.end(), {p[0], p[1], p[2]});
  }
  return pts;
}

void BM_FitPlanes(benchmark::State& state) {
  VoxelMap map(0.5, 20, 0.05, 40.0, 200000);
  const auto m = room_points(200000, 0.02, 1);
  map.insert(m.data(), m.size() / 3, Eigen::Vector3d(0, 0, 1.5));
  const auto scan = room_points(static_cast<std::size_t>(state.range(0)), 0.02, 2);
  PlaneParams prm;
  prm.neighbours = 10;
  prm.max_neighbour_distance = 0.3;
  std::vector<std::uint8_t> valid(scan.size() / 3);
  std::vector<double> planes(4 * valid.size());
  for (auto _ : state) {
    map.fit_planes(scan.data(), valid.size(), Eigen::Matrix3d::Identity(), Eigen::Vector3d::Zero(), prm, valid.data(),
                   planes.data(), static_cast<int>(state.range(1)));
    benchmark::DoNotOptimize(planes.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<long>(valid.size()));
}
BENCHMARK(BM_FitPlanes)->Args({2500, 1})->Args({2500, 2})->Unit(benchmark::kMillisecond);

void BM_Deskew(benchmark::State& state) {
  const std::size_t n_imu = 22, n = 20000;
  std::vector<double> dt(n_imu, 0.005), acc, gyr, states(10 * (n_imu + 1)), rates(6 * n_imu), knot_t(n_imu + 1);
  for (std::size_t k = 0; k < n_imu; ++k) {
    acc.insert(acc.end(), {0.3, -0.1, 9.9});
    gyr.insert(gyr.end(), {0.1, 0.2, 0.8});
  }
  for (std::size_t k = 0; k <= n_imu; ++k) knot_t[k] = 0.005 * static_cast<double>(k);
  propagate(NavState{}, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, -9.81), dt.data(),
            acc.data(), gyr.data(), n_imu, states.data(), rates.data());
  const Trajectory traj{knot_t.data(), states.data(), rates.data(), n_imu + 1};
  std::vector<float> pts(3 * n, 3.0f);
  std::vector<double> t(n), out(3 * n);
  for (std::size_t i = 0; i < n; ++i) t[i] = 0.1 * static_cast<double>(i) / n;
  for (auto _ : state) {
    deskew(pts.data(), t.data(), n, traj, 0.1, Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity(), out.data(),
           static_cast<int>(state.range(0)));
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<long>(n));
}
BENCHMARK(BM_Deskew)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

void BM_VoxelDownsample(benchmark::State& state) {
  const auto pts = room_points(20000, 0.02, 3);
  for (auto _ : state) benchmark::DoNotOptimize(voxel_downsample(pts.data(), pts.size() / 3, 0.05));
  state.SetItemsProcessed(state.iterations() * 20000);
}
BENCHMARK(BM_VoxelDownsample)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace cufund::odometry
BENCHMARK_MAIN();
