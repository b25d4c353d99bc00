#include "env_batch.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

#include "thread_pool.h"

namespace cufund {

namespace {

std::uint64_t splitmix64(std::uint64_t& x) {
  std::uint64_t z = (x += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

inline std::uint64_t rotl(std::uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

bool range_ok(const std::vector<double>& r, double lo) {
  return r.size() == 2 && std::isfinite(r[0]) && std::isfinite(r[1]) && lo <= r[0] && r[0] <= r[1];
}

// R_WB row-major of q_WB [w, x, y, z], normalised in the formula (s = 2 / |q|^2): policy_observation.rotation_rows.
void rotation_rows(const double q[4], double R[9]) {
  const double qw = q[0], qx = q[1], qy = q[2], qz = q[3];
  const double s = 2.0 / (qw * qw + qx * qx + qy * qy + qz * qz);
  R[0] = 1.0 - s * (qy * qy + qz * qz);
  R[1] = s * (qx * qy - qw * qz);
  R[2] = s * (qx * qz + qw * qy);
  R[3] = s * (qx * qy + qw * qz);
  R[4] = 1.0 - s * (qx * qx + qz * qz);
  R[5] = s * (qy * qz - qw * qx);
  R[6] = s * (qx * qz - qw * qy);
  R[7] = s * (qy * qz + qw * qx);
  R[8] = 1.0 - s * (qx * qx + qy * qy);
}

}  // namespace

void EnvBatch::Rng::seed(std::uint64_t x) {
  for (auto& w : s) w = splitmix64(x);
  has_spare = false;
}

std::uint64_t EnvBatch::Rng::next() {
  const std::uint64_t result = rotl(s[1] * 5, 7) * 9;
  const std::uint64_t t = s[1] << 17;
  s[2] ^= s[0];
  s[3] ^= s[1];
  s[1] ^= s[2];
  s[0] ^= s[3];
  s[2] ^= t;
  s[3] = rotl(s[3], 45);
  return result;
}

double EnvBatch::Rng::uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

double EnvBatch::Rng::normal() {  // Box-Muller: two values per pair of uniforms, the second kept for the next call
  if (has_spare) {
    has_spare = false;
    return spare;
  }
  const double u1 = 1.0 - uniform();  // (0, 1]
  const double u2 = uniform();
  const double r = std::sqrt(-2.0 * std::log(u1));
  spare = r * std::sin(2.0 * M_PI * u2);
  has_spare = true;
  return r * std::cos(2.0 * M_PI * u2);
}

bool EnvTaskParams::physical_randomisation() const {
  for (const auto* r : {&mass, &inertia, &motor_constant, &motor_lag, &drag}) {
    if ((*r)[0] != 1.0 || (*r)[1] != 1.0) return true;
  }
  return false;
}

std::string validate(const EnvTaskParams& t) {
  std::ostringstream e;
  if (!(std::isfinite(t.dt) && t.dt > 0))
    e << "dt must be a finite number > 0 [s], got " << t.dt;
  else if (t.substeps < 1)
    e << "substeps must be >= 1, got " << t.substeps;
  else if (t.max_steps < 1)
    e << "max_steps must be >= 1, got " << t.max_steps;
  else if (t.targets.empty() || t.targets.size() % 4 != 0)
    e << "targets must hold K x 4 numbers (K >= 1)";
  else if (t.n_ahead < 1)
    e << "n_ahead must be >= 1, got " << t.n_ahead;
  else if (t.spawn_center.size() != 3 || t.spawn_extent.size() != 3)
    e << "spawn_center and spawn_extent need 3";
  else if (!range_ok(t.mass, 1e-3))
    e << "mass must be a range [lo, hi] with 0.001 <= lo <= hi";
  else if (!range_ok(t.inertia, 1e-3))
    e << "inertia must be a range [lo, hi] with 0.001 <= lo <= hi";
  else if (!range_ok(t.motor_constant, 1e-3))
    e << "motor_constant must be a range [lo, hi] with 0.001 <= lo <= hi";
  else if (!range_ok(t.motor_lag, 1e-3))
    e << "motor_lag must be a range [lo, hi] with 0.001 <= lo <= hi";
  else if (!range_ok(t.drag, 0.0))
    e << "drag must be a range [lo, hi] with 0 <= lo <= hi";
  else if (!range_ok(t.latency_steps, 0.0) || t.latency_steps[1] > EnvBatch::kMaxLatency)
    e << "latency_steps must be a range [lo, hi] with 0 <= lo <= hi <= " << EnvBatch::kMaxLatency;
  else if (!range_ok(t.wind, 0.0))
    e << "wind must be a range [lo, hi] with 0 <= lo <= hi [m/s]";
  else if (!range_ok(t.position_noise, 0.0))
    e << "position_noise must be a range [lo, hi] with 0 <= lo <= hi [m]";
  else if (!range_ok(t.velocity_noise, 0.0))
    e << "velocity_noise must be a range [lo, hi] with 0 <= lo <= hi";
  else if (!range_ok(t.segment_s, 0.0) || (t.segment_s[1] > 0 && t.segment_s[0] <= 0))
    e << "segment_s must be a range [lo, hi] with 0 < lo <= hi [s], or [0, 0] (no timed reference)";
  else if (!range_ok(t.hold_s, 0.0))
    e << "hold_s must be a range [lo, hi] with 0 <= lo <= hi [s]";
  else if (t.waypoint_jitter.size() != 3 ||
           !(t.waypoint_jitter[0] >= 0 && t.waypoint_jitter[1] >= 0 && t.waypoint_jitter[2] >= 0 &&
             std::isfinite(t.waypoint_jitter[0]) && std::isfinite(t.waypoint_jitter[1]) &&
             std::isfinite(t.waypoint_jitter[2])))
    e << "waypoint_jitter must be 3 finite numbers >= 0 [m]";
  else if (!(std::isfinite(t.lookahead) && t.lookahead >= 0))
    e << "lookahead must be a finite number >= 0 [s], got " << t.lookahead;
  else if (!(std::isfinite(t.w_smooth) && t.w_smooth >= 0))
    e << "w_smooth must be a finite number >= 0, got " << t.w_smooth;
  for (double x : t.targets) {
    if (!std::isfinite(x)) return "targets must be finite numbers";
  }
  return e.str();
}

EnvBatch::EnvBatch(const QuadrotorParams& params, const EnvTaskParams& task, std::size_t n)
    : params_(params), task_(task), n_(n), batch_(params, n) {
  const std::string err = validate(task);
  if (!err.empty()) throw std::invalid_argument(err);
  omega_hover_ = batch_.hover_rotor_speed();
  omega_span_ = std::min(params.rotor_speed_max - omega_hover_, omega_hover_ - params.rotor_speed_min);
  if (!(omega_span_ > 0)) throw std::invalid_argument("the vehicle cannot hover within its rotor-speed limits");
  max_thrust_ = 4.0 * params.k_f * params.rotor_speed_max * params.rotor_speed_max;
  rng_.resize(n);
  for (std::size_t i = 0; i < n; ++i) rng_[i].seed(i);
  if (task.physical_randomisation()) constants_.assign(n, make_constants(params));
  if (task.action_mode != ActionMode::kRotorSpeeds) {
    rate_.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
      rate_.emplace_back(params, task.rate_d_cutoff_hz, task.rate_i_scale);
      rate_.back().set_gains(task.rate_gains);
    }
  }
  a_prev_.assign(4 * n, 0.0);
  a_last_.assign(4 * n, 0.0);
  if (task.reference()) {
    const std::size_t K = static_cast<std::size_t>(task.n_targets());
    wp_.assign(3 * K * n, 0.0);
    seg_.assign(2 * (K - 1) * n, 0.0);
    ref_.assign(9 * n, 0.0);
  }
  ring_ = static_cast<int>(task.latency_steps[1]) + 1;
  history_.assign(4 * n * ring_, 0.0);
  applied_.assign(4 * n, 0.0);
  cmd_.assign(4 * n, omega_hover_);
  prev_p_.assign(3 * n, 0.0);
  gyro_bias_.assign(6 * n, 0.0);
  noise_std_.assign(2 * n, 0.0);
  scales_.assign(5 * n, 1.0);
  index_.assign(n, 0);
  steps_.assign(n, 0);
  latency_.assign(n, 0);
  head_.assign(n, 0);
  done_.assign(n, 0);
}

void EnvBatch::reset(std::uint64_t seed, float* obs) {
  for (std::size_t i = 0; i < n_; ++i) rng_[i].seed(seed + i);
  reset(obs);
}

void EnvBatch::reset(float* obs) {
  batch_.reset();
  for (std::size_t i = 0; i < n_; ++i) {
    reset_env(i);
    observe(i, obs + i * obs_size());
  }
}

// Draws, in this order: the scales of mass, inertia, k_f, tau_m, drag; the latency; wind speed and direction; the
// position and velocity noise deviations; position (3), velocity (3), roll, pitch, yaw, body rate (3); the gyro's
// turn-on bias (3).
void EnvBatch::reset_env(std::size_t i) {
  Rng& g = rng_[i];
  const EnvTaskParams& t = task_;
  double* sc = &scales_[5 * i];
  sc[0] = g.uniform(t.mass[0], t.mass[1]);
  sc[1] = g.uniform(t.inertia[0], t.inertia[1]);
  sc[2] = g.uniform(t.motor_constant[0], t.motor_constant[1]);
  sc[3] = g.uniform(t.motor_lag[0], t.motor_lag[1]);
  sc[4] = g.uniform(t.drag[0], t.drag[1]);
  if (!constants_.empty()) {
    QuadrotorParams p = params_;
    p.mass *= sc[0];
    p.inertia *= sc[1];
    p.k_f *= sc[2];
    p.tau_m *= sc[3];
    p.rotor_drag_xy *= sc[4];
    p.rotor_drag_z *= sc[4];
    p.body_drag *= sc[4];
    constants_[i] = make_constants(p);
  }
  const double lat = std::floor(g.uniform(t.latency_steps[0], t.latency_steps[1] + 1.0));
  latency_[i] = static_cast<int>(std::min(lat, t.latency_steps[1]));
  const double wind = g.uniform(t.wind[0], t.wind[1]);
  const double wind_dir = g.uniform(-M_PI, M_PI);
  noise_std_[2 * i] = g.uniform(t.position_noise[0], t.position_noise[1]);
  noise_std_[2 * i + 1] = g.uniform(t.velocity_noise[0], t.velocity_noise[1]);
  QuadrotorBatch& b = batch_;
  for (int k = 0; k < 3; ++k)
    b.row(QuadrotorBatch::kP + k)[i] = t.spawn_center[k] + g.uniform(-1, 1) * t.spawn_extent[k];
  for (int k = 0; k < 3; ++k) b.row(QuadrotorBatch::kV + k)[i] = g.uniform(-1, 1) * t.spawn_speed;
  const double roll = g.uniform(-t.spawn_tilt, t.spawn_tilt), pitch = g.uniform(-t.spawn_tilt, t.spawn_tilt);
  const double yaw = g.uniform(-M_PI, M_PI);
  const double cr = std::cos(roll / 2), sr = std::sin(roll / 2), cp = std::cos(pitch / 2), sp = std::sin(pitch / 2);
  const double cy = std::cos(yaw / 2), sy = std::sin(yaw / 2);
  b.row(QuadrotorBatch::kQ)[i] = cr * cp * cy + sr * sp * sy;
  b.row(QuadrotorBatch::kQ + 1)[i] = sr * cp * cy - cr * sp * sy;
  b.row(QuadrotorBatch::kQ + 2)[i] = cr * sp * cy + sr * cp * sy;
  b.row(QuadrotorBatch::kQ + 3)[i] = cr * cp * sy - sr * sp * cy;
  for (int k = 0; k < 3; ++k) b.row(QuadrotorBatch::kW + k)[i] = g.uniform(-1, 1) * t.spawn_rate;
  const double hover = std::sqrt(params_.mass * sc[0] * params_.gravity / (kNumRotors * params_.k_f * sc[2]));
  for (int k = 0; k < 4; ++k) b.row(QuadrotorBatch::kRotor + k)[i] = hover;
  b.row(QuadrotorBatch::kWind)[i] = wind * std::cos(wind_dir);
  b.row(QuadrotorBatch::kWind + 1)[i] = wind * std::sin(wind_dir);
  b.row(QuadrotorBatch::kWind + 2)[i] = 0.0;
  for (int k = 0; k < 3; ++k) {
    gyro_bias_[6 * i + k] = t.imu_noise ? g.normal() * t.gyro_turn_on : 0.0;
    gyro_bias_[6 * i + 3 + k] = 0.0;
  }
  if (t.reference()) {  // drawn last: the other tasks' streams are unchanged
    const int K = t.n_targets();
    double* wp = &wp_[3 * K * i];
    for (int k = 0; k < K; ++k) {
      for (int j = 0; j < 3; ++j) wp[3 * k + j] = t.targets[4 * k + j] + g.uniform(-1, 1) * t.waypoint_jitter[j];
    }
    double* seg = seg_.data() + 2 * (K - 1) * i;
    for (int k = 0; k + 1 < K; ++k) {
      seg[2 * k] = g.uniform(t.hold_s[0], t.hold_s[1]);
      seg[2 * k + 1] = g.uniform(t.segment_s[0], t.segment_s[1]);
    }
    for (int j = 0; j < 3; ++j) b.row(QuadrotorBatch::kP + j)[i] += wp[j] - t.targets[j];  // around the first
    reference_at(i, 0.0, &ref_[9 * i]);
  }
  std::fill(&a_prev_[4 * i], &a_prev_[4 * i] + 4, 0.0);
  std::fill(&a_last_[4 * i], &a_last_[4 * i] + 4, 0.0);
  std::fill(&history_[4 * i * ring_], &history_[4 * (i + 1) * ring_], 0.0);
  head_[i] = 0;
  steps_[i] = 0;
  index_[i] = 0;
  done_[i] = 0;
  if (!rate_.empty()) {
    rate_[i].reset();
  }
}

// Minimum-jerk segments: s = (t - t0) / T, p = a + (b - a) (10 s^3 - 15 s^4 + 6 s^5).
void EnvBatch::reference_at(std::size_t i, double t, double out[9]) const {
  const int K = task_.n_targets();
  const double* wp = wp_.data() + 3 * K * i;
  const double* seg = seg_.data() + 2 * (K - 1) * i;
  double t0 = 0.0;
  int rest = K - 1;  // the waypoint the reference rests at (past the last segment: the last)
  for (int k = 0; k + 1 < K; ++k) {
    const double hold = seg[2 * k], T = seg[2 * k + 1];
    if (t < t0 + hold) {
      rest = k;
      break;
    }
    if (t < t0 + hold + T) {
      const double s = (t - t0 - hold) / T, s2 = s * s, s3 = s2 * s;
      const double f = s3 * (10.0 - 15.0 * s + 6.0 * s2);
      const double df = 30.0 * s2 * (1.0 - 2.0 * s + s2) / T;
      const double ddf = 60.0 * s * (1.0 - 3.0 * s + 2.0 * s2) / (T * T);
      for (int j = 0; j < 3; ++j) {
        const double dl = wp[3 * (k + 1) + j] - wp[3 * k + j];
        out[j] = wp[3 * k + j] + dl * f;
        out[3 + j] = dl * df;
        out[6 + j] = dl * ddf;
      }
      return;
    }
    t0 += hold + T;
  }
  for (int j = 0; j < 3; ++j) {
    out[j] = wp[3 * rest + j];
    out[3 + j] = out[6 + j] = 0.0;
  }
}

// policy_observation.build_observation for env i, in its order of operations.
void EnvBatch::observe(std::size_t i, float* out) {
  const EnvTaskParams& t = task_;
  const QuadrotorBatch& b = batch_;
  const double p[3] = {b.row(QuadrotorBatch::kP)[i], b.row(QuadrotorBatch::kP + 1)[i],
                       b.row(QuadrotorBatch::kP + 2)[i]};
  const int K = t.n_targets();
  const double sp = noise_std_[2 * i], sv = noise_std_[2 * i + 1];
  const bool pos_noise = t.position_noise[1] > 0, vel_noise = t.velocity_noise[1] > 0;
  int o = 0;
  for (int k = 0; k < t.n_ahead; ++k) {
    const double* tg = &t.targets[4 * std::min(index_[i] + k, K - 1)];
    double ahead[3];
    if (t.reference()) {  // policy_observation.lookahead_targets
      const double* r = &ref_[9 * i];
      const double tau = k * t.lookahead;
      for (int j = 0; j < 3; ++j) ahead[j] = r[j] + r[3 + j] * tau + 0.5 * r[6 + j] * tau * tau;
      tg = ahead;
    }
    for (int j = 0; j < 3; ++j) {
      double rel = tg[j] - p[j];
      if (pos_noise) rel += sp * rng_[i].normal();
      out[o++] = static_cast<float>(rel);
    }
    if (t.task == EnvTask::kGates) {
      out[o++] = static_cast<float>(std::cos(tg[3]));
      out[o++] = static_cast<float>(std::sin(tg[3]));
      out[o++] = 0.0f;
    }
  }
  for (int j = 0; j < 3; ++j) {
    double v = b.row(QuadrotorBatch::kV + j)[i];
    if (vel_noise) v += sv * rng_[i].normal();
    out[o++] = static_cast<float>(v);
  }
  const double q[4] = {b.row(QuadrotorBatch::kQ)[i], b.row(QuadrotorBatch::kQ + 1)[i], b.row(QuadrotorBatch::kQ + 2)[i],
                       b.row(QuadrotorBatch::kQ + 3)[i]};
  double R[9];
  rotation_rows(q, R);
  for (int k = 0; k < 9; ++k) out[o++] = static_cast<float>(R[k]);
  double* gb = &gyro_bias_[6 * i];
  double white[3] = {0, 0, 0}, walk_step[3] = {0, 0, 0};
  if (t.imu_noise) {
    for (int j = 0; j < 3; ++j) white[j] = rng_[i].normal() * (t.gyro_white / std::sqrt(t.dt));
    for (int j = 0; j < 3; ++j) walk_step[j] = rng_[i].normal() * (t.gyro_walk * std::sqrt(t.dt));
  }
  for (int j = 0; j < 3; ++j) {
    double w = b.row(QuadrotorBatch::kW + j)[i];
    if (t.imu_noise) {
      w += gb[j] + gb[3 + j] + white[j];
      gb[3 + j] += walk_step[j];
    }
    out[o++] = static_cast<float>(w);
  }
  for (int j = 0; j < 4; ++j) out[o++] = static_cast<float>(a_prev_[4 * i + j]);
}

void velocity_command(const VelocityCommandGains& k, const double a[4], const double v_W[3], const double q_WB[4],
                      double* thrust, Eigen::Vector3d* w_sp) {
  double rows[9];
  rotation_rows(q_WB, rows);
  const Eigen::Matrix3d R = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(rows);
  Eigen::Vector3d acc;
  for (int j = 0; j < 3; ++j) acc[j] = k.velocity_gain * (a[j] * k.max_speed - v_W[j]);
  acc[2] = std::max(acc[2] + k.gravity, 0.2 * k.gravity);  // never command a free fall
  const Eigen::Vector3d z_B = R.col(2);
  *thrust = std::clamp(k.mass * acc.dot(z_B), 0.0, k.max_thrust);
  const Eigen::Vector3d err_B = R.transpose() * z_B.cross(acc.normalized());
  *w_sp = Eigen::Vector3d(k.attitude_gain * err_B[0], k.attitude_gain * err_B[1], a[3] * k.max_rate);
}

// Rotor-speed commands from the applied (delayed) actions.
void EnvBatch::commands(const double* applied, int nthreads) {
  const EnvTaskParams& t = task_;
  QuadrotorBatch& b = batch_;
  if (t.action_mode == ActionMode::kRotorSpeeds) {
    for (std::size_t k = 0; k < 4 * n_; ++k) cmd_[k] = omega_hover_ + applied[k] * omega_span_;
    return;
  }
  const double m = params_.mass, g = params_.gravity;
  const VelocityCommandGains vel{m, g, max_thrust_, t.max_speed, t.max_rate, t.velocity_gain, t.attitude_gain};
  ThreadPool::instance().parallel_for((n_ + 255) / 256, nthreads, [&](std::size_t blk) {
    const std::size_t end = std::min(n_, (blk + 1) * 256);
    for (std::size_t i = blk * 256; i < end; ++i) {
      const double* a = applied + 4 * i;
      const Eigen::Vector3d w_B(b.row(QuadrotorBatch::kW)[i], b.row(QuadrotorBatch::kW + 1)[i],
                                b.row(QuadrotorBatch::kW + 2)[i]);
      double thrust;
      Eigen::Vector3d w_sp;
      if (t.action_mode == ActionMode::kThrustRates) {
        thrust = std::min(m * g * (1.0 + a[0]), max_thrust_);
        w_sp = Eigen::Vector3d(a[1], a[2], a[3]) * t.max_rate;
      } else {
        const double v[3] = {b.row(QuadrotorBatch::kV)[i], b.row(QuadrotorBatch::kV + 1)[i],
                             b.row(QuadrotorBatch::kV + 2)[i]};
        const double q[4] = {b.row(QuadrotorBatch::kQ)[i], b.row(QuadrotorBatch::kQ + 1)[i],
                             b.row(QuadrotorBatch::kQ + 2)[i], b.row(QuadrotorBatch::kQ + 3)[i]};
        velocity_command(vel, a, v, q, &thrust, &w_sp);
      }
      const AllocationResult r = rate_[i].step(w_B, w_sp, thrust, t.dt);
      for (int k = 0; k < 4; ++k) cmd_[4 * i + k] = r.rotor_speeds[k];
    }
  });
}

namespace {

template <bool kGround>
void integrate_env(const DynamicsConstants& c, QuadrotorBatch& b, std::size_t i, const double* cmd, double h,
                   int substeps) {
  double x[kStateSize];
  for (int j = 0; j < kStateSize; ++j) x[j] = b.row(j)[i];
  StepInputs u;
  for (int k = 0; k < kNumRotors; ++k) {
    u.omega_cmd[k] = std::min(std::max(cmd[4 * i + k], c.omega_min), b.row(QuadrotorBatch::kOmegaMax)[i]);
    u.eta[k] = b.row(QuadrotorBatch::kEta + k)[i];
  }
  for (int k = 0; k < 3; ++k) {
    u.wind_W[k] = b.row(QuadrotorBatch::kWind + k)[i];
    u.force_W[k] = b.row(QuadrotorBatch::kForceExt + k)[i];
    u.torque_B[k] = b.row(QuadrotorBatch::kTorqueExt + k)[i];
  }
  u.floor_z = b.row(QuadrotorBatch::kFloorZ)[i];
  u.ceiling_z = b.row(QuadrotorBatch::kCeilingZ)[i];
  for (int s = 0; s < substeps; ++s) rk4_substep<kGround, false>(c, u, h, x);
  for (int j = 0; j < kStateSize; ++j) b.row(j)[i] = x[j];
  double dx[kStateSize];
  derivative<kGround, false>(c, x, u, dx);
  const bool held = kGround && resting_on_ground(x);
  for (int k = 0; k < 3; ++k) {
    b.row(QuadrotorBatch::kAccel + k)[i] = held ? 0.0 : dx[3 + k];
    b.row(QuadrotorBatch::kAlpha + k)[i] = held ? 0.0 : dx[10 + k];
  }
}

}  // namespace

void EnvBatch::integrate(int nthreads) {
  const double dt = task_.dt;
  if (constants_.empty()) {  // one parameter set: the batch's own vectorised step
    const StepResult r = batch_.step(dt, cmd_.data(), nthreads);
    if (r.status != StepStatus::kOk && r.status != StepStatus::kDiverged) {
      throw std::runtime_error("the dynamics refused the step (status " + std::to_string(static_cast<int>(r.status)) +
                               ", index " + std::to_string(r.index) + ")");
    }
    return;
  }
  const int substeps = task_.substeps;
  const double h = dt / substeps;
  const bool ground = params_.ground_plane;
  ThreadPool::instance().parallel_for((n_ + 255) / 256, nthreads, [&](std::size_t blk) {
    const std::size_t end = std::min(n_, (blk + 1) * 256);
    for (std::size_t i = blk * 256; i < end; ++i) {
      if (ground) {
        integrate_env<true>(constants_[i], batch_, i, cmd_.data(), h, substeps);
      } else {
        integrate_env<false>(constants_[i], batch_, i, cmd_.data(), h, substeps);
      }
    }
  });
  batch_.set_time(batch_.time() + dt);
}

void EnvBatch::step(const double* actions, float* obs, double* reward, bool* terminated, bool* truncated,
                    int nthreads) {
  unsigned bad = 0;
  for (std::size_t k = 0; k < 4 * n_; ++k) bad |= static_cast<unsigned>(!std::isfinite(actions[k]));
  if (bad != 0) {
    for (std::size_t k = 0; k < 4 * n_; ++k) {
      if (!std::isfinite(actions[k])) {
        throw std::invalid_argument("actions must be finite numbers in [-1, 1]; env " + std::to_string(k / 4) +
                                    " has a NaN or inf at index " + std::to_string(k % 4));
      }
    }
  }
  // The given actions (clipped) enter each env's delay line; the applied one is `latency` steps old.
  if (task_.w_smooth > 0) std::copy(a_prev_.begin(), a_prev_.end(), a_last_.begin());
  for (std::size_t k = 0; k < 4 * n_; ++k) a_prev_[k] = std::clamp(actions[k], -1.0, 1.0);
  if (ring_ == 1) {
    std::copy(a_prev_.begin(), a_prev_.end(), applied_.begin());
  } else {
    const int L = ring_;
    for (std::size_t i = 0; i < n_; ++i) {
      double* hist = &history_[4 * i * L];
      head_[i] = head_[i] + 1 == L ? 0 : head_[i] + 1;
      for (int k = 0; k < 4; ++k) hist[4 * head_[i] + k] = a_prev_[4 * i + k];
      const int src = head_[i] >= latency_[i] ? head_[i] - latency_[i] : head_[i] - latency_[i] + L;
      for (int k = 0; k < 4; ++k) applied_[4 * i + k] = hist[4 * src + k];
    }
  }
  for (int k = 0; k < 3; ++k) {
    const double* row = batch_.row(QuadrotorBatch::kP + k);
    for (std::size_t i = 0; i < n_; ++i) prev_p_[3 * i + k] = row[i];
  }
  commands(applied_.data(), nthreads);
  integrate(nthreads);
  ThreadPool::instance().parallel_for((n_ + kBlock - 1) / kBlock, nthreads, [&](std::size_t blk) {
    finish_block(blk * kBlock, std::min(n_, (blk + 1) * kBlock), obs, reward, terminated, truncated);
  });
}

// After the dynamics: env i's reward, flags and observation (or its autoreset).
void EnvBatch::finish_block(std::size_t begin, std::size_t end, float* obs, double* reward, bool* terminated,
                            bool* truncated) {
  // The norms first, in loops across envs that vectorise (the same arithmetic as one env at a time).
  double d[kBlock], speed[kBlock], rate[kBlock], a2[kBlock];
  const QuadrotorBatch& b = batch_;
  const double *px = b.row(QuadrotorBatch::kP), *py = b.row(QuadrotorBatch::kP + 1),
               *pz = b.row(QuadrotorBatch::kP + 2);
  const double *vx = b.row(QuadrotorBatch::kV), *vy = b.row(QuadrotorBatch::kV + 1),
               *vz = b.row(QuadrotorBatch::kV + 2);
  const double *wx = b.row(QuadrotorBatch::kW), *wy = b.row(QuadrotorBatch::kW + 1),
               *wz = b.row(QuadrotorBatch::kW + 2);
  const double* targets = task_.targets.data();
  const int* index = index_.data();
  const double* ap = a_prev_.data();
  const std::size_t m = end - begin;
  if (task_.reference()) {  // the reference at the step's end; the distance and speed relative to it
    for (std::size_t j = 0; j < m; ++j) {
      const std::size_t i = begin + j;
      double* r = &ref_[9 * i];
      reference_at(i, (steps_[i] + 1) * task_.dt, r);
      const double ex = r[0] - px[i], ey = r[1] - py[i], ez = r[2] - pz[i];
      d[j] = std::sqrt(ex * ex + ey * ey + ez * ez);
      const double ux = vx[i] - r[3], uy = vy[i] - r[4], uz = vz[i] - r[5];
      speed[j] = std::sqrt(ux * ux + uy * uy + uz * uz);
      rate[j] = std::sqrt(wx[i] * wx[i] + wy[i] * wy[i] + wz[i] * wz[i]);
      const double* a = ap + 4 * i;
      a2[j] = a[0] * a[0] + a[1] * a[1] + a[2] * a[2] + a[3] * a[3];
    }
  }
  for (std::size_t j = 0; j < m && !task_.reference(); ++j) {
    const std::size_t i = begin + j;
    const double* tg = targets + 4 * index[i];
    const double ex = tg[0] - px[i], ey = tg[1] - py[i], ez = tg[2] - pz[i];
    d[j] = std::sqrt(ex * ex + ey * ey + ez * ez);
    speed[j] = std::sqrt(vx[i] * vx[i] + vy[i] * vy[i] + vz[i] * vz[i]);
    rate[j] = std::sqrt(wx[i] * wx[i] + wy[i] * wy[i] + wz[i] * wz[i]);
    const double* a = ap + 4 * i;
    a2[j] = a[0] * a[0] + a[1] * a[1] + a[2] * a[2] + a[3] * a[3];
  }
  const std::size_t stride = static_cast<std::size_t>(obs_size());
  for (std::size_t j = 0; j < m; ++j) {
    const std::size_t i = begin + j;
    finish(i, obs + i * stride, reward, terminated, truncated, d[j], speed[j], rate[j], a2[j]);
  }
}

void EnvBatch::finish(std::size_t i, float* o, double* reward, bool* terminated, bool* truncated, double d,
                      const double speed, const double rate, const double a2) {
  const EnvTaskParams& t = task_;
  QuadrotorBatch& b = batch_;
  const int K = t.n_targets();
  const double half = 0.5 * t.gate_size;
  {
    if (done_[i]) {  // next-step autoreset: the action was ignored
      reset_env(i);
      reward[i] = 0.0;
      terminated[i] = truncated[i] = false;
      observe(i, o);
      return;
    }
    double p[3];
    for (int k = 0; k < 3; ++k) p[k] = b.row(QuadrotorBatch::kP + k)[i];
    const double* tg = &t.targets[4 * index_[i]];
    double r = t.alive - t.w_position * d - t.w_velocity * speed - t.w_rate * rate - t.w_action * a2;
    if (t.w_smooth > 0) {
      const double* a = &a_prev_[4 * i];
      const double* l = &a_last_[4 * i];
      double s2 = 0.0;
      for (int k = 0; k < 4; ++k) s2 += (a[k] - l[k]) * (a[k] - l[k]);
      r -= t.w_smooth * s2;
    }
    bool crash = false, success = false;
    if (t.task != EnvTask::kHover && !t.reference()) {
      const double* pp = &prev_p_[3 * i];  // where the step started
      const double d_prev = std::sqrt((tg[0] - pp[0]) * (tg[0] - pp[0]) + (tg[1] - pp[1]) * (tg[1] - pp[1]) +
                                      (tg[2] - pp[2]) * (tg[2] - pp[2]));
      r += t.progress * (d_prev - d);
      bool passed = false;
      if (t.task == EnvTask::kWaypoints) {
        passed = d < t.reach_radius;
      } else {
        const double nx = std::cos(tg[3]), ny = std::sin(tg[3]);
        const double side = nx * (p[0] - tg[0]) + ny * (p[1] - tg[1]);
        const double s0 = nx * (pp[0] - tg[0]) + ny * (pp[1] - tg[1]);
        if (s0 < 0.0 && side >= 0.0) {  // crossed the gate's plane forwards: where?
          const double f = s0 / (s0 - side);
          double x[3];  // the crossing point relative to the gate centre, on the chord of the step
          for (int k = 0; k < 3; ++k) x[k] = pp[k] + (p[k] - pp[k]) * f - tg[k];
          const double lat = std::fabs(-ny * x[0] + nx * x[1]), up = std::fabs(x[2]);
          if (lat <= half && up <= half) {
            passed = true;
          } else if (lat <= 2.0 * half && up <= 2.0 * half) {
            crash = true;  // the frame
          }
        }
      }
      if (passed) {
        r += t.reached;
        if (index_[i] + 1 >= K) {
          success = true;
        } else {
          ++index_[i];
          tg = &t.targets[4 * index_[i]];
          d = std::sqrt((tg[0] - p[0]) * (tg[0] - p[0]) + (tg[1] - p[1]) * (tg[1] - p[1]) +
                        (tg[2] - p[2]) * (tg[2] - p[2]));
        }
      }
    }
    const bool finite = std::isfinite(d) && std::isfinite(speed) && std::isfinite(rate);
    crash = crash || !finite || d > t.bound || p[2] < t.crash_z;
    if (crash) r -= t.crash;
    if (!finite) {  // keep the batch steppable until the reset in the next step
      r = -t.crash;
      for (int k = 0; k < 3; ++k) {
        b.row(QuadrotorBatch::kP + k)[i] = t.spawn_center[k];
        b.row(QuadrotorBatch::kV + k)[i] = 0.0;
        b.row(QuadrotorBatch::kW + k)[i] = 0.0;
      }
      b.row(QuadrotorBatch::kQ)[i] = 1.0;
      for (int k = 1; k < 4; ++k) b.row(QuadrotorBatch::kQ + k)[i] = 0.0;
      for (int k = 0; k < 4; ++k) b.row(QuadrotorBatch::kRotor + k)[i] = omega_hover_;
    }
    ++steps_[i];
    reward[i] = r;
    terminated[i] = crash || success;
    truncated[i] = !terminated[i] && steps_[i] >= t.max_steps;
    done_[i] = terminated[i] || truncated[i];
    observe(i, o);
  }
}

}  // namespace cufund
