#include "quadrotor_batch.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "quadrotor_dynamics.h"

#include "thread_pool.h"

namespace cufund {

DynamicsConstants make_constants(const QuadrotorParams& p) {
  DynamicsConstants c{};
  c.inv_mass = 1.0 / p.mass;
  c.gravity = p.gravity;
  const Eigen::Matrix3d J_inv = p.inertia.inverse();
  CUFUND_UNROLL
  for (int i = 0; i < 3; ++i) {
    CUFUND_UNROLL
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
  CUFUND_UNROLL
  for (int i = 0; i < kNumRotors; ++i) {
    CUFUND_UNROLL
    for (int k = 0; k < 3; ++k) c.r[i][k] = g.position_B[i](k);
    c.yaw_moment[i] = -g.spin[i] * p.c_m;
  }
  c.kd_xy = p.rotor_drag_xy;
  c.kd_z = p.rotor_drag_z;
  CUFUND_UNROLL
  for (int k = 0; k < 3; ++k) c.cd[k] = p.body_drag(k);
  return c;
}

namespace {

using Rows = double* __restrict[QuadrotorBatch::kRows];

CUFUND_INLINE void load(const DynamicsConstants& c, const Rows& p, const double* __restrict cmd, std::size_t i,
                        double* x, StepInputs& u) {
  CUFUND_UNROLL
  for (int j = 0; j < kStateSize; ++j) x[j] = p[j][i];
  CUFUND_UNROLL
  for (int k = 0; k < kNumRotors; ++k) u.omega_cmd[k] = std::min(std::max(cmd[4 * i + k], c.omega_min), c.omega_max);
  CUFUND_UNROLL
  for (int k = 0; k < 3; ++k) {
    u.wind_W[k] = p[QuadrotorBatch::kWind + k][i];
    u.force_W[k] = p[QuadrotorBatch::kForceExt + k][i];
    u.torque_B[k] = p[QuadrotorBatch::kTorqueExt + k][i];
  }
}

// Integrates vehicles [begin, end): the loop body is one vehicle, so the compiler maps vehicles to
// SIMD lanes. Compiled for several instruction sets and picked at load time where the compiler can.
template <bool kGround>
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && !defined(CUFUND_NO_TARGET_CLONES)
__attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#endif
void integrate_range(const DynamicsConstants& constants, double* __restrict state, std::size_t n, std::size_t begin,
                     std::size_t end, const double* __restrict cmd, double h, int substeps) {
  const DynamicsConstants c = constants;  // a local copy: provably not aliased by the state stores
  Rows p;
  CUFUND_UNROLL
  for (int r = 0; r < QuadrotorBatch::kRows; ++r) p[r] = state + r * n;
  for (int s = 0; s < substeps; ++s) {
#if defined(__GNUC__)
#pragma GCC ivdep
#endif
    for (std::size_t i = begin; i < end; ++i) {
      double x[kStateSize];
      StepInputs u;
      load(c, p, cmd, i, x, u);
      rk4_substep<kGround>(c, u, h, x);
      CUFUND_UNROLL
      for (int j = 0; j < kStateSize; ++j) p[j][i] = x[j];
    }
  }
  // The true accelerations of the integrated model at the new state: what an IMU senses.
#if defined(__GNUC__)
#pragma GCC ivdep
#endif
  for (std::size_t i = begin; i < end; ++i) {
    double x[kStateSize], dx[kStateSize];
    StepInputs u;
    load(c, p, cmd, i, x, u);
    derivative<kGround>(c, x, u, dx);
    const bool held = kGround && resting_on_ground(x);
    CUFUND_UNROLL
    for (int k = 0; k < 3; ++k) {
      p[QuadrotorBatch::kAccel + k][i] = held ? 0.0 : dx[3 + k];
      p[QuadrotorBatch::kAlpha + k][i] = held ? 0.0 : dx[10 + k];
    }
  }
}

}  // namespace

namespace {
std::size_t checked_size(std::size_t n) {
  if (n < 1 || n > QuadrotorBatch::kMaxSize) throw std::length_error("QuadrotorBatch size out of range");
  return n;
}
}  // namespace

QuadrotorBatch::QuadrotorBatch(const QuadrotorParams& params, std::size_t n)
    : params_(params), n_(checked_size(n)), state_(static_cast<std::size_t>(kRows) * n_, 0.0) {
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
  if (!(std::isfinite(dt) && dt > 0.0 && dt / params_.max_integration_step <= 1e9)) {
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
  const bool ground = params_.ground_plane;
  ThreadPool::instance().parallel_for(nblocks, nthreads, [&](std::size_t b) {
    const std::size_t begin = b * kBlock;
    const std::size_t end = std::min(n_, begin + kBlock);
    if (ground) {
      integrate_range<true>(c, state, n_, begin, end, cmd, h, substeps);
    } else {
      integrate_range<false>(c, state, n_, begin, end, cmd, h, substeps);
    }
  });
  time_ += dt;
  return result;
}

}  // namespace cufund
