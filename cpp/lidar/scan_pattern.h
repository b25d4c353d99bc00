// Scan patterns computed in C++ (the arithmetic of cufund.sensors.patterns, which calls these).
#pragma once

#include <cstddef>
#include <cstdint>

namespace cufund::lidar {

// Livox Mid-360-like non-repetitive pattern (cufund.sensors.patterns.Mid360Pattern): frame k of n rays,
// `lasers` beams spaced evenly in azimuth turning at spin_rate [Hz], their elevations sweeping
// [elevation_min, elevation_max] [rad] sinusoidally sweep_ratio times per revolution. Writes, per ray i:
// t[i] (from the frame start) [s], azimuth[i], elevation[i] [rad], channel[i] and the unit direction
// d_L[3i..3i+3). nthreads <= 0 uses every core.
struct Mid360Params {
  double point_rate = 0.0;  // [1/s]
  std::int64_t lasers = 1;
  double spin_rate = 0.0;  // [Hz]
  double sweep_ratio = 0.0;
  double elevation_min = 0.0, elevation_max = 0.0;  // [rad]
};

void mid360_frame(const Mid360Params& p, std::int64_t k, std::size_t n, double* t, double* azimuth, double* elevation,
                  std::int32_t* channel, double* d_L, int nthreads);

}  // namespace cufund::lidar
