#pragma once

#include <vector>

#include "quadrotor_batch.h"

namespace cufund::testing {

// A Crazyflie-like vehicle (RotorPy's crazyflie_params) with drag switched off unless asked.
inline QuadrotorParams small_quad() {
  QuadrotorParams p;
  p.mass = 0.03;
  p.inertia << 1.43e-5, 0, 0, 0, 1.43e-5, 0, 0, 0, 2.89e-5;
  p.arm_length = 0.043;
  p.k_f = 2.3e-8;
  p.c_m = 7.8e-10 / 2.3e-8;
  p.tau_m = 0.072;
  p.rotor_speed_min = 0.0;
  p.rotor_speed_max = 2500.0;
  return p;
}

// Steps a single vehicle `steps` times with a constant command.
inline void run(QuadrotorBatch& b, double dt, int steps, const std::vector<double>& cmd) {
  for (int k = 0; k < steps; ++k) b.step(dt, cmd.data(), 1);
}

inline void set_row(QuadrotorBatch& b, int field, std::initializer_list<double> values, std::size_t i = 0) {
  int r = 0;
  for (double v : values) b.row(field + r++)[i] = v;
}

}  // namespace cufund::testing
