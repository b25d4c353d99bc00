#include "quadrotor_batch.h"

#include <Eigen/LU>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "quadrotor_dynamics.h"

#include "target_clones.h"
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
  CUFUND_UNROLL
  for (int k = 0; k < 4; ++k) c.ground_q[k] = p.ground_attitude(k);
  c.ge = GroundEffectParams{};
  return c;
}

namespace {

using Rows = double* __restrict[QuadrotorBatch::kRows];

// Most vehicles integrate_range takes at once (step()'s blocks).
constexpr std::size_t kIntegrateBlock = 256;

template <bool kGroundEffect>
CUFUND_INLINE void load(const DynamicsConstants& c, const Rows& p, const double* __restrict cmd, std::size_t i,
                        double* x, StepInputs& u) {
  CUFUND_UNROLL
  for (int j = 0; j < kStateSize; ++j) x[j] = p[j][i];
  CUFUND_UNROLL
  for (int k = 0; k < kNumRotors; ++k) {
    u.omega_cmd[k] = std::min(std::max(cmd[4 * i + k], c.omega_min), p[QuadrotorBatch::kOmegaMax][i]);
    u.eta[k] = p[QuadrotorBatch::kEta + k][i];
  }
  u.floor_z = p[QuadrotorBatch::kFloorZ][i];
  u.ceiling_z = p[QuadrotorBatch::kCeilingZ][i];
  CUFUND_UNROLL
  for (int k = 0; k < 3; ++k) {
    u.wind_W[k] = p[QuadrotorBatch::kWind + k][i];
    u.force_W[k] = p[QuadrotorBatch::kForceExt + k][i];
    u.torque_B[k] = p[QuadrotorBatch::kTorqueExt + k][i];
  }
  if constexpr (kGroundEffect) ground_effect_gains(c, x, u);
}

// Integrates vehicles [begin, end): the loop body is one vehicle, so the compiler maps vehicles to
// SIMD lanes. Compiled for several instruction sets and picked at load time where the compiler can.
// Returns false when the new state or its accelerations hold a NaN or inf (inputs beyond the model).
template <bool kGround, bool kGroundEffect>
CUFUND_TARGET_CLONES bool integrate_range(const DynamicsConstants& constants, double* __restrict state, std::size_t n,
                                          std::size_t begin, std::size_t end, const double* __restrict cmd, double h,
                                          int substeps) {
  const DynamicsConstants c = constants;  // a local copy: provably not aliased by the state stores
  Rows p;
  CUFUND_UNROLL
  for (int r = 0; r < QuadrotorBatch::kRows; ++r) p[r] = state + r * n;
  // With the ground effect: the last sub-step's gains, reused for the accelerations below (held over the sub-step
  // like the integration holds them; evaluating them again cost as much as the integration's own evaluation).
  [[maybe_unused]] double last_gain[kIntegrateBlock][kNumRotors];
  for (int s = 0; s < substeps; ++s) {
#if defined(__GNUC__)
#pragma GCC ivdep
#endif
    for (std::size_t i = begin; i < end; ++i) {
      double x[kStateSize];
      StepInputs u;
      load<kGroundEffect>(c, p, cmd, i, x, u);
      if constexpr (kGroundEffect) {
        CUFUND_UNROLL
        for (int k = 0; k < kNumRotors; ++k) last_gain[i - begin][k] = u.thrust_gain[k];
      }
      rk4_substep<kGround, kGroundEffect>(c, u, h, x);
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
    load<false>(c, p, cmd, i, x, u);
    if constexpr (kGroundEffect) {
      CUFUND_UNROLL
      for (int k = 0; k < kNumRotors; ++k) u.thrust_gain[k] = last_gain[i - begin][k];
    }
    derivative<kGround, kGroundEffect>(c, x, u, dx);
    const bool held = kGround && resting_on_ground(x);
    CUFUND_UNROLL
    for (int k = 0; k < 3; ++k) {
      p[QuadrotorBatch::kAccel + k][i] = held ? 0.0 : dx[3 + k];
      p[QuadrotorBatch::kAlpha + k][i] = held ? 0.0 : dx[10 + k];
    }
  }
  // Finiteness of the new state and accelerations, row by row over the block (cache-hot; each row's
  // loop is an OR reduction, which vectorises).
  unsigned bad = 0;
  for (int r = QuadrotorBatch::kP; r < QuadrotorBatch::kFloorZ; ++r) {
    if (r >= QuadrotorBatch::kWind && r < QuadrotorBatch::kAccel) continue;  // held inputs, checked before
    const double* row = p[r];
    for (std::size_t i = begin; i < end; ++i) bad |= static_cast<unsigned>(!std::isfinite(row[i]));
  }
  return bad == 0;
}

}  // namespace

namespace {

std::atomic<std::int64_t> g_max_substeps{1000000};

// True when rows [kP, kAccel) of vehicles [begin, end) are finite and every quaternion is non-zero:
// OR reductions, which vectorise (the common case costs a pass over the block).
bool block_ok(const double* state, std::size_t n, std::size_t begin, std::size_t end) {
  unsigned bad = 0;
  for (int r = QuadrotorBatch::kP; r < QuadrotorBatch::kAccel; ++r) {
    const double* row = state + static_cast<std::size_t>(r) * n;
    for (std::size_t i = begin; i < end; ++i) bad |= static_cast<unsigned>(!std::isfinite(row[i]));
  }
  const double* q = state + static_cast<std::size_t>(QuadrotorBatch::kQ) * n;
  for (std::size_t i = begin; i < end; ++i) {
    const double nq = q[i] * q[i] + q[n + i] * q[n + i] + q[2 * n + i] * q[2 * n + i] + q[3 * n + i] * q[3 * n + i];
    bad |= static_cast<unsigned>(!(nq >= 1e-12));
  }
  return bad == 0;
}

// The first offending entry (lowest row, then vehicle), after block_ok failed somewhere.
StepResult locate_bad_state(const double* state, std::size_t n) {
  StepResult r;
  for (int row = QuadrotorBatch::kP; row < QuadrotorBatch::kAccel; ++row) {
    const double* p = state + static_cast<std::size_t>(row) * n;
    for (std::size_t i = 0; i < n; ++i) {
      if (!std::isfinite(p[i])) {
        r.status = StepStatus::kNonFiniteState;
        r.index = static_cast<std::int64_t>(static_cast<std::size_t>(row) * n + i);
        return r;
      }
    }
  }
  const double* q = state + static_cast<std::size_t>(QuadrotorBatch::kQ) * n;
  for (std::size_t i = 0; i < n; ++i) {
    if (!(q[i] * q[i] + q[n + i] * q[n + i] + q[2 * n + i] * q[2 * n + i] + q[3 * n + i] * q[3 * n + i] >= 1e-12)) {
      r.status = StepStatus::kZeroQuaternion;
      r.index = static_cast<std::int64_t>(i);
      return r;
    }
  }
  return r;
}

StepResult check_state(const double* state, std::size_t n, int nthreads) {
  constexpr std::size_t kBlock = 4096;
  bool ok = true;
  if (n <= kBlock) {
    ok = block_ok(state, n, 0, n);
  } else {
    std::atomic<bool> all_ok{true};
    ThreadPool::instance().parallel_for((n + kBlock - 1) / kBlock, nthreads, [&](std::size_t b) {
      const std::size_t begin = b * kBlock;
      if (!block_ok(state, n, begin, std::min(n, begin + kBlock))) all_ok.store(false, std::memory_order_relaxed);
    });
    ok = all_ok.load();
  }
  return ok ? StepResult{} : locate_bad_state(state, n);
}

std::size_t checked_size(std::size_t n) {
  if (n < 1 || n > QuadrotorBatch::kMaxSize) throw std::length_error("QuadrotorBatch size out of range");
  return n;
}
}  // namespace

QuadrotorBatch::QuadrotorBatch(const QuadrotorParams& params, std::size_t n)
    : params_(params), n_(checked_size(n)), state_(static_cast<std::size_t>(kRows) * n_, 0.0) {
  reset();
}

QuadrotorBatch::QuadrotorBatch(const QuadrotorBatch& other) : params_(other.params_), ge_(other.ge_), n_(other.n_) {
  std::lock_guard<std::mutex> lk(other.mutex_);
  atmosphere_ = other.atmosphere_;
  time_ = other.time_;
  state_ = other.state_;
}

QuadrotorBatch& QuadrotorBatch::operator=(const QuadrotorBatch& other) {
  if (this == &other) return *this;
  std::scoped_lock lk(mutex_, other.mutex_);
  params_ = other.params_;
  ge_ = other.ge_;
  atmosphere_ = other.atmosphere_;
  n_ = other.n_;
  time_ = other.time_;
  state_ = other.state_;
  return *this;
}

std::int64_t QuadrotorBatch::max_substeps() { return g_max_substeps.load(); }

void QuadrotorBatch::set_max_substeps(std::int64_t n) { g_max_substeps.store(std::max<std::int64_t>(1, n)); }

double QuadrotorBatch::time() const {
  std::lock_guard<std::mutex> lk(mutex_);
  return time_;
}

bool QuadrotorBatch::set_time(double t) {
  if (!std::isfinite(t)) return false;
  std::lock_guard<std::mutex> lk(mutex_);
  time_ = t;
  return true;
}

void QuadrotorBatch::reset() {
  ForkSafeSection no_fork;
  std::lock_guard<std::mutex> lk(mutex_);
  std::fill(state_.begin(), state_.end(), 0.0);
  std::fill(row(kQ), row(kQ) + n_, 1.0);
  for (int k = 0; k < kNumRotors; ++k) std::fill(row(kEta + k), row(kEta + k) + n_, 1.0);
  std::fill(row(kOmegaMax), row(kOmegaMax) + n_, params_.rotor_speed_max);
  const double inf = std::numeric_limits<double>::infinity();
  std::fill(row(kFloorZ), row(kFloorZ) + n_, params_.ground_plane ? 0.0 : -inf);
  std::fill(row(kCeilingZ), row(kCeilingZ) + n_, inf);
  atmosphere_.reset();
  time_ = 0.0;
}

void QuadrotorBatch::set_atmosphere(const AtmosphereParams& a) {
  std::lock_guard<std::mutex> lk(mutex_);
  atmosphere_ = Atmosphere(a, n_);
}

void QuadrotorBatch::clear_atmosphere() {
  std::lock_guard<std::mutex> lk(mutex_);
  atmosphere_ = Atmosphere();
}

void QuadrotorBatch::set_ground_effect(const GroundEffectParams& g) {
  std::lock_guard<std::mutex> lk(mutex_);
  ge_ = g;
}

double QuadrotorBatch::hover_rotor_speed() const {
  return std::sqrt(params_.mass * params_.gravity / (kNumRotors * params_.k_f));
}

StepResult QuadrotorBatch::step(double dt, const double* cmd, int nthreads) {
  StepResult result;
  ForkSafeSection no_fork;
  std::lock_guard<std::mutex> lk(mutex_);
  if (!(std::isfinite(dt) && dt > 0.0 && dt / params_.max_integration_step <= 1e9)) {
    result.status = StepStatus::kBadTimeStep;
    return result;
  }
  if (dt / params_.max_integration_step > static_cast<double>(g_max_substeps.load()) + 1e-6) {
    result.status = StepStatus::kTooManySubsteps;
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
  if (atmosphere_.enabled()) atmosphere_.update(time_, row(kP), row(kV), row(kWind), n_);
  result = check_state(state_.data(), n_, nthreads);
  if (result.status != StepStatus::kOk) return result;
  const int substeps = std::max(1, static_cast<int>(std::ceil(dt / params_.max_integration_step - 1e-9)));
  const double h = dt / substeps;
  DynamicsConstants c = make_constants(params_);
  c.ge = ge_;
  const bool ge = ge_.enabled;

  // Blocks of vehicles small enough to stay in L1/L2 across sub-steps.
  constexpr std::size_t kBlock = kIntegrateBlock;
  const std::size_t nblocks = (n_ + kBlock - 1) / kBlock;
  double* state = state_.data();
  const bool ground = params_.ground_plane;
  std::atomic<bool> diverged{false};
  ThreadPool::instance().parallel_for(nblocks, nthreads, [&](std::size_t b) {
    const std::size_t begin = b * kBlock;
    const std::size_t end = std::min(n_, begin + kBlock);
    bool ok;
    if (ge) {
      ok = ground ? integrate_range<true, true>(c, state, n_, begin, end, cmd, h, substeps)
                  : integrate_range<false, true>(c, state, n_, begin, end, cmd, h, substeps);
    } else {
      ok = ground ? integrate_range<true, false>(c, state, n_, begin, end, cmd, h, substeps)
                  : integrate_range<false, false>(c, state, n_, begin, end, cmd, h, substeps);
    }
    if (!ok) diverged.store(true, std::memory_order_relaxed);
  });
  time_ += dt;
  if (diverged.load()) {
    result = check_state(state, n_, nthreads);  // which vehicle and field
    result.status = StepStatus::kDiverged;
    if (result.index < 0) result.index = 0;
  }
  return result;
}

StepResult step_batches(const BatchStep* steps, std::size_t n, int nthreads, std::size_t* failed) {
  std::vector<StepResult> results(n);
  if (n == 1 || nthreads == 1) {
    for (std::size_t k = 0; k < n; ++k) results[k] = steps[k].batch->step(steps[k].dt, steps[k].cmd, 1);
  } else {
    ThreadPool::instance().parallel_for(
        n, nthreads, [&](std::size_t k) { results[k] = steps[k].batch->step(steps[k].dt, steps[k].cmd, 1); });
  }
  for (std::size_t k = 0; k < n; ++k) {
    if (results[k].status != StepStatus::kOk) {
      if (failed != nullptr) *failed = k;
      return results[k];
    }
  }
  return StepResult{};
}

}  // namespace cufund
