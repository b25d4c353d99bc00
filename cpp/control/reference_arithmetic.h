// Scalar arithmetic in the exact order the Python/numpy reference of the PX4-style loops performs it, so the C++
// loops reproduce the reference bit for bit (tests/test_control_kernels.py compares them on random inputs):
// numpy's 3- and 4-vector norms and dots (OpenBLAS's ddot: one fused multiply-add per element, in order) and
// Python's math.hypot (CPython's vector_norm: Dekker-split squares, compensated sums, one Newton correction),
// which can differ from std::hypot in the last bit. The file is compiled with -ffp-contract=off, so every other
// a * b + c rounds twice, as numpy's element-wise operations do.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <limits>

namespace cufund::reference_arithmetic {

// sum_i a_i b_i as OpenBLAS's ddot accumulates it for short vectors.
template <int N>
inline double dot(const Eigen::Matrix<double, N, 1>& a, const Eigen::Matrix<double, N, 1>& b) {
  double s = a[0] * b[0];
  for (int i = 1; i < N; ++i) s = std::fma(a[i], b[i], s);
  return s;
}

// numpy.linalg.norm of a short vector: sqrt(dot(v, v)).
template <int N>
inline double norm(const Eigen::Matrix<double, N, 1>& v) {
  return std::sqrt(dot<N>(v, v));
}

// Python's math.hypot(a, b).
inline double hypot(double a, double b) {
  constexpr double kSplit = 134217729.0;  // 2^27 + 1
  const double va = std::fabs(a), vb = std::fabs(b);
  double max = 0.0;  // a NaN never becomes the maximum: hypot(inf, nan) is inf
  if (va > max) max = va;
  if (vb > max) max = vb;
  if (std::isinf(max)) return max;
  if (std::isnan(a) || std::isnan(b)) return std::numeric_limits<double>::quiet_NaN();
  if (max == 0.0) return max;
  int max_e = 0;
  std::frexp(max, &max_e);
  if (max_e < -1023) {  // subnormal: scale to normal numbers first
    const double m = std::numeric_limits<double>::min();
    return m * hypot(a / m, b / m);
  }
  const double scale = std::ldexp(1.0, -max_e);
  double csum = 1.0, frac1 = 0.0, frac2 = 0.0, frac3 = 0.0;
  const auto add = [&csum](double x, double& frac) {
    const double old = csum;
    csum += x;
    frac += (old - csum) + x;
  };
  for (const double v : {va, vb}) {
    const double x = v * scale;
    const double t = x * kSplit;
    const double hi = t - (t - x);
    const double lo = x - hi;
    add(hi * hi, frac1);
    add(2.0 * hi * lo, frac2);
    frac3 += lo * lo;
  }
  const double h = std::sqrt(csum - 1.0 + (frac1 + frac2 + frac3));
  const double t = h * kSplit;
  const double hi = t - (t - h);
  const double lo = h - hi;
  add(-hi * hi, frac1);
  add(-2.0 * hi * lo, frac2);
  add(-lo * lo, frac3);
  const double x = csum - 1.0 + (frac1 + frac2 + frac3);
  return (h + x / (2.0 * h)) / scale;
}

// Python's max(a, b) and min(a, b) for floats (the first argument wins ties and NaN comparisons), and numpy's
// element-wise maximum / minimum with a bound (NaN propagates from x).
inline double py_max(double a, double b) { return b > a ? b : a; }
inline double py_min(double a, double b) { return b < a ? b : a; }
inline double clamp(double x, double lo, double hi) { return py_min(py_max(x, lo), hi); }

// numpy.sign as the saturation flags use it: +1, -1, or 0 (also for NaN, which no comparison counts).
inline int sign(double x) { return x > 0 ? 1 : (x < 0 ? -1 : 0); }

}  // namespace cufund::reference_arithmetic
