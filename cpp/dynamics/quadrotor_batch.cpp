#include "quadrotor_batch.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>

#include "quadrotor_dynamics.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace cufund {

DynamicsConstants make_constants(const QuadrotorParams& p) {
  DynamicsConstants c{};
  c.inv_mass = 1.0 / p.mass;
  c.gravity = p.gravity;
  const Eigen::Matrix3d J_inv = p.inertia.inverse();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      c.J[3 * i + j] = p.inertia(i, j);
      c.J_inv[3 * i + j] = J_inv(i, j);
    }
  }
  c.k_f = p.k_f;
  c.inv_tau_m = 1.0 / p.tau_m;
  c.omega_min = p.rotor_speed_min;
  c.omega_max = p.rotor_speed_max;
  const RotorGeometry g = rotor_geometry(p);
  for (int i = 0; i < kNumRotors; ++i) {
    for (int k = 0; k < 3; ++k) c.r[i][k] = g.position_B[i](k);
    c.yaw_moment[i] = -g.spin[i] * p.c_m;
  }
  c.kd_xy = p.rotor_drag_xy;
  c.kd_z = p.rotor_drag_z;
  for (int k = 0; k < 3; ++k) c.cd[k] = p.body_drag(k);
  c.ground = p.ground_plane;
  return c;
}

namespace {

// Integrates vehicles [begin, end): the loop body is one vehicle, so the compiler maps vehicles to
// SIMD lanes. Compiled for several instruction sets and picked at load time where the compiler can.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && !defined(CUFUND_NO_TARGET_CLONES)
__attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#endif
void integrate_range(const DynamicsConstants& c, double* __restrict state, std::size_t n, std::size_t begin,
                     std::size_t end, const double* __restrict cmd, double h, int substeps) {
  for (int s = 0; s < substeps; ++s) {
#if defined(__GNUC__)
#pragma GCC ivdep
#endif
    for (std::size_t i = begin; i < end; ++i) {
      double x[kStateSize];
      for (int j = 0; j < kStateSize; ++j) x[j] = state[j * n + i];
      StepInputs u;
      for (int k = 0; k < kNumRotors; ++k) {
        u.omega_cmd[k] = std::min(std::max(cmd[4 * i + k], c.omega_min), c.omega_max);
      }
      for (int k = 0; k < 3; ++k) {
        u.wind_W[k] = state[(QuadrotorBatch::kWind + k) * n + i];
        u.force_W[k] = state[(QuadrotorBatch::kForceExt + k) * n + i];
        u.torque_B[k] = state[(QuadrotorBatch::kTorqueExt + k) * n + i];
      }
      rk4_substep(c, u, h, x);
      for (int j = 0; j < kStateSize; ++j) state[j * n + i] = x[j];
    }
  }
}

}  // namespace

QuadrotorBatch::QuadrotorBatch(const QuadrotorParams& params, std::size_t n)
    : params_(params), n_(n), state_(static_cast<std::size_t>(kRows) * n, 0.0) {
  reset();
}

void QuadrotorBatch::reset() {
  std::fill(state_.begin(), state_.end(), 0.0);
  std::fill(row(kQ), row(kQ) + n_, 1.0);
  time_ = 0.0;
}

double QuadrotorBatch::hover_rotor_speed() const {
  return std::sqrt(params_.mass * params_.gravity / (kNumRotors * params_.k_f));
}

StepResult QuadrotorBatch::step(double dt, const double* cmd, int nthreads) {
  StepResult result;
  if (!(std::isfinite(dt) && dt > 0.0)) {
    result.status = StepStatus::kBadTimeStep;
    return result;
  }
  const std::size_t ncmd = kNumRotors * n_;
  for (std::size_t k = 0; k < ncmd; ++k) {
    if (!std::isfinite(cmd[k])) {
      result.status = StepStatus::kNonFiniteCommand;
      result.index = static_cast<std::int64_t>(k);
      return result;
    }
  }
  const int substeps = std::max(1, static_cast<int>(std::ceil(dt / params_.max_integration_step - 1e-9)));
  const double h = dt / substeps;
  const DynamicsConstants c = make_constants(params_);

  // Blocks of vehicles small enough to stay in L1/L2 across sub-steps.
  constexpr std::size_t kBlock = 256;
  const std::size_t nblocks = (n_ + kBlock - 1) / kBlock;
  double* state = state_.data();
#ifdef _OPENMP
  const int threads = nthreads > 0 ? nthreads : omp_get_max_threads();
#pragma omp parallel for schedule(static) num_threads(threads) if (nblocks > 1 && threads > 1)
#else
  (void)nthreads;
#endif
  for (std::ptrdiff_t b = 0; b < static_cast<std::ptrdiff_t>(nblocks); ++b) {
    const std::size_t begin = static_cast<std::size_t>(b) * kBlock;
    const std::size_t end = std::min(n_, begin + kBlock);
    integrate_range(c, state, n_, begin, end, cmd, h, substeps);
  }
  time_ += dt;
  return result;
}

}  // namespace cufund
