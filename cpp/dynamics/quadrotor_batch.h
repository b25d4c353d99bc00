// N quadrotors with identical parameters, integrated together (paper §2.1, eqs. 2-5).
//
// State is structure-of-arrays: component c of field F for vehicle i lives at F(c)[i], so the
// inner loop runs across vehicles in SIMD lanes and numpy sees each field as an (N, k) view
// with strides (8, 8N). Every vehicle is integrated by the same scalar arithmetic
// (no FMA contraction), so a batch of N equals N batches of one bit for bit, on any thread count.
// Thread safety: step(), reset() and the time lock an internal mutex (concurrent steps run one after
// the other); a step also holds off fork() (ForkSafeSection) so a child never sees a half step.
#pragma once

#include <cstddef>
#include <cstdint>
#include <mutex>
#include <vector>

#include "atmosphere.h"
#include "ground_effect.h"
#include "quadrotor_params.h"

namespace cufund {

enum class StepStatus : int {
  kOk = 0,
  kBadTimeStep = 1,       // dt not finite, <= 0, or more than 1e9 integration sub-steps
  kNonFiniteCommand = 2,  // a commanded rotor speed is NaN or infinite
  kNonFiniteState = 3,    // a state or held-input entry (rows kP..kTorqueExt) is NaN or infinite
  kZeroQuaternion = 4,    // an attitude quaternion of norm < 1e-6
  kTooManySubsteps = 5,   // dt / max_integration_step exceeds the configured limit
  kDiverged = 6,          // the step ran, but the new state is NaN or inf (inputs beyond the model's range);
                          // index as for kNonFiniteState (row * N + vehicle), time advanced
};

struct StepResult {
  StepStatus status = StepStatus::kOk;
  std::int64_t index = -1;  // kNonFiniteCommand: vehicle * 4 + rotor; kNonFiniteState: row * N + vehicle;
                            // kZeroQuaternion: the vehicle
};

class QuadrotorBatch {
 public:
  // Field layout inside the state buffer, in units of N doubles.
  enum Field : int {
    kP = 0,           // position p_W [m], 3 rows
    kV = 3,           // velocity v_W [m/s], 3 rows
    kQ = 6,           // attitude q_WB [w, x, y, z], 4 rows
    kW = 10,          // body rate w_B [rad/s], 3 rows
    kRotor = 13,      // rotor speeds [rad/s], 4 rows
    kWind = 17,       // wind velocity in world frame [m/s], 3 rows (held over a step)
    kForceExt = 20,   // external force in world frame [N], 3 rows (held over a step)
    kTorqueExt = 23,  // external torque in body frame [N m], 3 rows (held over a step)
    kEta = 26,        // rotor efficiency in [0, 1]: scales thrust and drag torque, 4 rows (default 1; persists)
    kOmegaMax = 30,   // upper clamp of the rotor speed command [rad/s], 1 row (default params' max; persists)
    kAccel = 31,      // acceleration a_W = dv_W/dt at the end of the last step [m/s^2], 3 rows (output)
    kAlpha = 34,      // angular acceleration dw_B/dt at the end of the last step [rad/s^2], 3 rows (output)
    kFloorZ = 37,     // floor height under the vehicle [m] (-inf: none), 1 row; read with the ground effect only
    kCeilingZ = 38,   // ceiling height over the vehicle [m] (+inf: none), 1 row; read with the ground effect only
    kRows = 39,
  };

  // Most vehicles in one batch (2^32; the state alone is then 1 TiB).
  static constexpr std::size_t kMaxSize = std::size_t(1) << 32;

  // Most RK4 sub-steps one step() may take (dt / max_integration_step), process-wide; default 1e6
  // (1000 s at 1 kHz). A larger dt fails with kTooManySubsteps instead of running for minutes.
  static std::int64_t max_substeps();
  static void set_max_substeps(std::int64_t n);  // n >= 1

  // params must have passed validate(); 1 <= n <= kMaxSize (else std::length_error).
  QuadrotorBatch(const QuadrotorParams& params, std::size_t n);
  // Copies parameters, state and time (each under the source's lock); the copy has its own mutex.
  QuadrotorBatch(const QuadrotorBatch& other);
  QuadrotorBatch& operator=(const QuadrotorBatch& other);

  std::size_t size() const { return n_; }
  const QuadrotorParams& params() const { return params_; }
  double time() const;
  // false (time unchanged) unless t is finite.
  bool set_time(double t);

  double* row(int r) { return state_.data() + static_cast<std::size_t>(r) * n_; }
  const double* row(int r) const { return state_.data() + static_cast<std::size_t>(r) * n_; }

  // Every vehicle at rest at p_W = (0, 0, 0), level, rotors stopped, no wind or disturbance; rotor efficiency 1,
  // rotor speed limit the parameters', floor at z = 0 with a ground plane (else none), no ceiling.
  void reset();

  // Ground and ceiling effect (ground_effect.h); off by default. g must have passed validate() when enabled.
  const GroundEffectParams& ground_effect() const { return ge_; }
  void set_ground_effect(const GroundEffectParams& g);

  // The atmosphere (atmosphere.h): when set, step() writes every vehicle's wind rows from it once per its update
  // period (replacing any wind written there). a must have passed validate(). reset() restarts it from its seed.
  bool has_atmosphere() const { return atmosphere_.enabled(); }
  const AtmosphereParams& atmosphere() const { return atmosphere_.params(); }
  void set_atmosphere(const AtmosphereParams& a);
  void clear_atmosphere();

  // Advances all vehicles by dt [s] holding rotor_speed_cmd (row-major (N, 4) [rad/s], clipped to the
  // rotor-speed limits) constant, in ceil(dt / max_integration_step) equal RK4 sub-steps.
  // nthreads <= 0: all available cores (cufund::ThreadPool).
  StepResult step(double dt, const double* rotor_speed_cmd, int nthreads = 0);

  // Hover rotor speed [rad/s]: all four rotors carrying m g / 4.
  double hover_rotor_speed() const;

 private:
  QuadrotorParams params_;
  GroundEffectParams ge_;
  Atmosphere atmosphere_;
  std::size_t n_;
  double time_ = 0.0;
  std::vector<double> state_;
  // step(), reset() and the time are serialised: concurrent calls from several threads run one after
  // the other. Writes through row() pointers (numpy views) are not synchronised.
  mutable std::mutex mutex_;
};

// One step of one batch within step_batches: advance `batch` by dt [s] holding cmd (row-major (size, 4) [rad/s]).
struct BatchStep {
  QuadrotorBatch* batch = nullptr;
  double dt = 0.0;
  const double* cmd = nullptr;
};

// Several batches (each its own parameters, state and time: e.g. the vehicles of a fleet, one batch each) stepped
// in one call: steps[k].batch->step(steps[k].dt, steps[k].cmd, 1) for every k, on at most nthreads threads over
// the batches (<= 0: all cores). Each batch is stepped by exactly that call (the same arithmetic, on one thread),
// so the result equals stepping them one by one, bit for bit, on any thread count. Every batch is stepped even when
// another fails; returns the first failure in k order (kOk when none) with its k in *failed (when not null).
// The batches must be distinct (a batch listed twice is stepped twice, in no defined order).
StepResult step_batches(const BatchStep* steps, std::size_t n, int nthreads = 1, std::size_t* failed = nullptr);

}  // namespace cufund
