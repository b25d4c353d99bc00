// Learning environments on the quadrotor batch (issue 28): actions -> rotor commands, the dynamics, observation,
// reward, termination and next-step autoreset of N envs in one call, with no per-vehicle Python.
//
// The observation layout is python/cufund/control/policy_observation.py's, computed in the same order (no FMA
// contraction), so the two agree bit for bit. Each env draws its resets, randomisation and noise from its own
// xoshiro256** stream seeded by splitmix64(seed + i): env i of a batch equals a batch of one seeded seed + i.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "quadrotor_batch.h"
#include "quadrotor_dynamics.h"
#include "rate_control.h"

namespace cufund {

enum class EnvTask : int { kHover = 0, kWaypoints = 1, kGates = 2 };
enum class ActionMode : int { kRotorSpeeds = 0, kThrustRates = 1, kVelocity = 2 };

struct EnvTaskParams {
  EnvTask task = EnvTask::kHover;
  ActionMode action_mode = ActionMode::kRotorSpeeds;
  double dt = 0.01;             // one env step [s]
  int substeps = 1;             // RK4 steps per env step
  int max_steps = 500;          // truncation
  std::vector<double> targets;  // K x 4: x, y, z [m], yaw [rad] (gates; else 0)
  int n_ahead = 1;
  double reach_radius = 0.1, gate_size = 0.5, bound = 2.0, crash_z = 0.02;
  std::vector<double> spawn_center{0.0, 0.0, 1.0}, spawn_extent{0.5, 0.5, 0.5};
  double spawn_speed = 0.2, spawn_tilt = 0.17, spawn_rate = 0.5;
  double max_rate = 10.0, max_speed = 2.0;
  double velocity_gain = 4.0, attitude_gain = 10.0;  // velocity mode: [1/s], [1/s]
  // rewards
  double w_position = 1.0, w_velocity = 0.05, w_rate = 0.02, w_action = 0.01, alive = 1.0, progress = 10.0,
         reached = 10.0, crash = 10.0;
  // randomisation ranges [lo, hi]
  std::vector<double> mass{1, 1}, inertia{1, 1}, motor_constant{1, 1}, motor_lag{1, 1}, drag{1, 1}, latency_steps{0, 0},
      wind{0, 0}, position_noise{0, 0}, velocity_noise{0, 0};
  // gyro noise (the IMU noise model: turn-on bias + bias random walk + white noise), per axis
  bool imu_noise = false;
  double gyro_white = 0.0, gyro_walk = 0.0, gyro_turn_on = 0.0;  // [rad/s/sqrt(Hz)], [rad/s^2/sqrt(Hz)], [rad/s]
  // the rate loop (thrust_rates, velocity)
  RateControlGains rate_gains{Eigen::Vector3d(25, 25, 12), Eigen::Vector3d(10, 10, 5), Eigen::Vector3d(0.2, 0.2, 0),
                              0.0, 30.0};
  double rate_d_cutoff_hz = 30.0, rate_i_scale = 6.981317007977318;
  // Waypoints with a timed reference (off while segment_s[1] == 0): the target is a point that moves from
  // waypoint to waypoint on minimum-jerk segments of a duration drawn in segment_s [s], resting hold_s [s] at each
  // waypoint before it leaves; each episode moves every waypoint by a uniform draw in +- waypoint_jitter [m] per
  // axis. Target block k of the observation is the reference extrapolated k * lookahead [s] ahead,
  // p + v tau + 0.5 a tau tau; the reward's distance is to the reference point and its velocity term to the
  // reference velocity; no progress or reached bonus, no success (the episode runs to truncation).
  std::vector<double> segment_s{0, 0}, hold_s{0, 0}, waypoint_jitter{0, 0, 0};
  double lookahead = 0.0;
  double w_smooth = 0.0;  // per unit of |a - a_prev|^2 (every task)
  bool reference() const { return task == EnvTask::kWaypoints && segment_s[1] > 0; }

  int target_dim() const { return task == EnvTask::kGates ? 6 : 3; }
  int obs_size() const { return n_ahead * target_dim() + 19; }
  int n_targets() const { return static_cast<int>(targets.size() / 4); }
  bool physical_randomisation() const;
};

// "" when the task parameters are usable, else a message naming the field.
std::string validate(const EnvTaskParams& t);

// The velocity action mode: action a (4) in [-1, 1] -> collective thrust [N] and body-rate setpoint [rad/s] for the
// rate loop. acc = velocity_gain (a_0..2 max_speed - v_W), acc_z + g (at least 0.2 g); thrust = clamp(m acc . z_B, 0,
// max_thrust); roll/pitch rates attitude_gain (R_WB^T (z_B x acc / |acc|))_xy; yaw rate a_3 max_rate. q_WB need not
// be unit. The envs and the policy controller (cufund.control.policy_action) both fly it.
struct VelocityCommandGains {
  double mass, gravity, max_thrust, max_speed, max_rate, velocity_gain, attitude_gain;
};
void velocity_command(const VelocityCommandGains& k, const double a[4], const double v_W[3], const double q_WB[4],
                      double* thrust, Eigen::Vector3d* w_sp);

class EnvBatch {
 public:
  static constexpr int kMaxLatency = 64;

  EnvBatch(const QuadrotorParams& params, const EnvTaskParams& task, std::size_t n);

  std::size_t size() const { return n_; }
  int obs_size() const { return task_.obs_size(); }
  const EnvTaskParams& task() const { return task_; }
  QuadrotorBatch& batch() { return batch_; }

  // Seeds env i's stream with seed + i and resets every env; writes obs (N, obs_size).
  void reset(std::uint64_t seed, float* obs);
  // Resets every env continuing their streams.
  void reset(float* obs);
  // One step of every env: actions (N, 4) in [-1, 1] (clipped; must be finite). Writes obs (N, obs_size), reward
  // (N), terminated (N), truncated (N). An env that ended in the previous call is reset instead (its action
  // ignored, reward 0, flags false). Throws std::invalid_argument on a non-finite action, std::runtime_error
  // when the dynamics refuse the step.
  void step(const double* actions, float* obs, double* reward, bool* terminated, bool* truncated, int nthreads = 0);
  // Ends the episodes of the envs with mask[i] (N) set, e.g. on a collision only the caller sees (ForestAvoid,
  // SwarmGates): the next step resets them (next-step autoreset).
  void end_episodes(const bool* mask) {
    for (std::size_t i = 0; i < n_; ++i) done_[i] = done_[i] || mask[i];
  }

  // Per env: current target index, steps in the episode, the action delay drawn [steps].
  const std::vector<int>& target_index() const { return index_; }
  const std::vector<int>& episode_steps() const { return steps_; }
  const std::vector<int>& latency() const { return latency_; }
  // Per env, 5 numbers drawn at the last reset: the scales of mass, inertia, k_f, tau_m and drag.
  const std::vector<double>& drawn_scales() const { return scales_; }
  // Reference mode: env i's reference position, velocity and acceleration (9) at time t [s] of its episode.
  void reference_at(std::size_t i, double t, double out[9]) const;
  // Reference mode: env i's waypoints (K x 3) as jittered at its last reset.
  std::vector<double> waypoints(std::size_t i) const {
    const std::size_t K = task_.n_targets();
    return std::vector<double>(wp_.begin() + 3 * K * i, wp_.begin() + 3 * K * (i + 1));
  }

 private:
  struct Rng {
    std::uint64_t s[4];
    double spare = 0.0;  // normal(): the second value of the last Box-Muller pair
    bool has_spare = false;
    void seed(std::uint64_t x);
    std::uint64_t next();
    double uniform();  // [0, 1)
    double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
    double normal();
  };

  void reset_env(std::size_t i);
  void observe(std::size_t i, float* out);
  void commands(const double* applied, int nthreads);
  void integrate(int nthreads);
  void finish_block(std::size_t begin, std::size_t end, float* obs, double* reward, bool* terminated, bool* truncated);
  // d: distance to the current target, speed |v_W|, rate |w_B|, a2 |a|^2 (finish_block computes them).
  void finish(std::size_t i, float* obs, double* reward, bool* terminated, bool* truncated, double d, double speed,
              double rate, double a2);

  static constexpr std::size_t kBlock = 256;  // envs per parallel chunk

  QuadrotorParams params_;
  EnvTaskParams task_;
  std::size_t n_;
  QuadrotorBatch batch_;
  double omega_hover_, omega_span_, max_thrust_;
  std::vector<Rng> rng_;
  std::vector<DynamicsConstants> constants_;  // per env, with physical randomisation only
  std::vector<RateControl> rate_;
  std::vector<double> wp_, seg_;  // reference mode: per env K x 3 waypoints, (K - 1) x 2 hold and move durations
  std::vector<double> ref_;       // reference mode: per env p, v, a of the reference at the current step
  std::vector<double> a_last_;    // the action before a_prev_ (the smoothness penalty)
  std::vector<double> a_prev_, history_, applied_, cmd_, prev_p_, gyro_bias_, noise_std_, scales_;
  std::vector<int> index_, steps_, latency_, head_;
  int ring_ = 1;  // delay-line length: the largest latency + 1
  std::vector<unsigned char> done_;
};

}  // namespace cufund
