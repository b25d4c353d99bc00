#include "scan_pattern.h"

#include "thread_pool.h"

#include <cmath>

namespace cufund::lidar {

void mid360_frame(const Mid360Params& p, std::int64_t k, std::size_t n, double* t, double* azimuth, double* elevation,
                  std::int32_t* channel, double* d_L, int nthreads) {
  // Operation for operation the NumPy expressions this replaced (the same bits): 2 * pi * (...) with
  // Python's left-to-right scalar products, fmod for np.mod of non-negative numbers.
  constexpr double kPi = 3.141592653589793;
  const double two_pi = 2 * kPi;
  const double phase_rate = 2 * kPi * p.spin_rate * p.sweep_ratio;
  const double mid = (p.elevation_max + p.elevation_min) / 2, half = (p.elevation_max - p.elevation_min) / 2;
  const double lasers = static_cast<double>(p.lasers);
  const auto first = k * static_cast<std::int64_t>(n);
  parallel_chunks(static_cast<std::ptrdiff_t>(n), 4096, nthreads,
                  [&](std::ptrdiff_t begin, std::ptrdiff_t end, std::ptrdiff_t) {
                    for (std::ptrdiff_t i = begin; i < end; ++i) {
                      const double t_abs = static_cast<double>(first + i) / p.point_rate;
                      const auto ch = static_cast<std::int32_t>(i % p.lasers);
                      const double c = static_cast<double>(ch);
                      const double az = std::fmod(two_pi * (p.spin_rate * t_abs + c / lasers), two_pi);
                      const double phase = phase_rate * t_abs + kPi * c / lasers;
                      const double el = mid + half * std::sin(phase);
                      const double ce = std::cos(el);
                      t[i] = static_cast<double>(i) / p.point_rate;
                      azimuth[i] = az;
                      elevation[i] = el;
                      channel[i] = ch;
                      d_L[3 * i] = ce * std::cos(az);
                      d_L[3 * i + 1] = ce * std::sin(az);
                      d_L[3 * i + 2] = std::sin(el);
                    }
                  });
}

}  // namespace cufund::lidar
