// State pieces the PX4-style loops share: the low-passed derivative their D terms act on and the bumpless
// hand-over at a mode switch. Element-wise arithmetic in the order of the Python reference (bit for bit, see
// reference_arithmetic.h).
#pragma once

#include <Eigen/Core>
#include <cmath>

namespace cufund {

// Backward difference of a sampled 3-vector through a first-order low-pass with cutoff cutoff_hz [Hz] (0: no
// filtering). The first sample gives a zero difference, so D does not kick at start-up.
class LowPassDerivative {
 public:
  explicit LowPassDerivative(double cutoff_hz) : cutoff_hz_(cutoff_hz) {}

  void reset() {
    value.setZero();
    has_prev_ = false;
  }

  // Takes the sample x that follows the previous one by dt [s]; returns the filtered derivative.
  const Eigen::Vector3d& update(const Eigen::Vector3d& x, double dt) {
    if (!has_prev_) {
      prev_ = x;
      has_prev_ = true;
    }
    const double alpha = cutoff_hz_ > 0 ? dt / (dt + 1.0 / (2.0 * M_PI * cutoff_hz_)) : 1.0;
    for (int i = 0; i < 3; ++i) value[i] += alpha * ((x[i] - prev_[i]) / dt - value[i]);
    prev_ = x;
    return value;
  }

  Eigen::Vector3d value = Eigen::Vector3d::Zero();  // the filtered derivative

 private:
  double cutoff_hz_;
  Eigen::Vector3d prev_ = Eigen::Vector3d::Zero();
  bool has_prev_ = false;
};

// The step a mode switch would cause in a 3-vector command: the command last given continues and fades into the
// new one with time constant tau [s].
class BumplessHandover {
 public:
  explicit BumplessHandover(double tau) : tau_(tau) {}

  void reset() { active_ = false; }

  // Adds the fading offset at time t [s] to cmd; handover (non-null at a mode switch) is the command last given,
  // from which the offset starts. With no offset, adds 0.0 (as the reference's `cmd + 0.0`: -0.0 becomes 0.0).
  void apply(double t, const Eigen::Vector3d* handover, Eigen::Vector3d& cmd) {
    if (handover != nullptr) {
      offset_ = *handover - cmd;
      t0_ = t;
      active_ = true;
    }
    if (active_) {
      const double decay = std::exp(-(t - t0_) / tau_);
      for (int i = 0; i < 3; ++i) cmd[i] += offset_[i] * decay;
    } else {
      for (int i = 0; i < 3; ++i) cmd[i] += 0.0;
    }
  }

 private:
  double tau_;
  Eigen::Vector3d offset_ = Eigen::Vector3d::Zero();
  double t0_ = 0.0;
  bool active_ = false;
};

}  // namespace cufund
