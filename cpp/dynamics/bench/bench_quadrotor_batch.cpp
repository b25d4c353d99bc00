// Micro-benchmarks of the dynamics hot loop: vehicle-steps per second for one vehicle and for batches.
#include <benchmark/benchmark.h>

#include <vector>

#include "quadrotor_batch.h"
#include "tests/test_helpers.h"

namespace {

cufund::QuadrotorParams crazyflie() {
  cufund::QuadrotorParams p = cufund::testing::small_quad();
  p.rotor_drag_xy = 10.2506e-07;
  p.rotor_drag_z = 7.553e-07;
  return p;
}

void BM_Step(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const int threads = static_cast<int>(state.range(1));
  cufund::QuadrotorBatch b(crazyflie(), n);
  const double wh = b.hover_rotor_speed();
  for (std::size_t i = 0; i < n; ++i) {
    b.row(cufund::QuadrotorBatch::kP + 2)[i] = 100.0;
    for (int k = 0; k < 4; ++k) b.row(cufund::QuadrotorBatch::kRotor + k)[i] = wh;
  }
  std::vector<double> cmd(4 * n);
  for (std::size_t i = 0; i < cmd.size(); ++i) cmd[i] = wh * (1.0 + 1e-3 * static_cast<double>(i % 7));
  for (auto _ : state) {
    b.step(1e-3, cmd.data(), threads);
    benchmark::DoNotOptimize(b.row(0));
  }
  state.counters["vehicle_steps_per_s"] =
      benchmark::Counter(static_cast<double>(n) * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

BENCHMARK(BM_Step)->Args({1, 1})->Args({4096, 1})->Args({4096, 2})->Args({100000, 2})->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
