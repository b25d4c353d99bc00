// The one-dimensional kernels every Euclidean distance transform in cpp/esdf is built from:
// the distance to the nearest site along a line (two linear scans), and the lower envelope of
// parabolas of Felzenszwalb & Huttenlocher, "Distance Transforms of Sampled Functions" (2012).
#pragma once

#include <cstddef>
#include <limits>
#include <vector>

namespace cufund::esdf {

inline constexpr double kInf = std::numeric_limits<double>::infinity();

// Buffers of the lower-envelope pass for `lines` lines of length n handled together: their input f
// and output d, and one line's envelope (parabola vertices v, boundaries z).
struct LineBuffers {
  LineBuffers(std::ptrdiff_t lines, std::ptrdiff_t n)
      : f(static_cast<std::size_t>(lines * n)),
        d(static_cast<std::size_t>(lines * n)),
        v(static_cast<std::size_t>(n)),
        z(static_cast<std::size_t>(n + 1)) {}
  std::vector<double> f, d;
  std::vector<std::ptrdiff_t> v;
  std::vector<double> z;
};

// d[q] = (spacing * |q - p|)^2 for the nearest p with site[p * stride] != 0, +inf if the line has none.
inline void squared_distance_to_sites_1d(const unsigned char* site, std::ptrdiff_t stride, std::ptrdiff_t n,
                                         double spacing, double* d) {
  // Forward pass: distance to the nearest site at or before q; backward pass: the nearer side.
  std::ptrdiff_t last = -1;
  for (std::ptrdiff_t q = 0; q < n; ++q) {
    if (site[q * stride]) last = q;
    d[q] = last < 0 ? kInf : spacing * static_cast<double>(q - last);
  }
  last = -1;
  for (std::ptrdiff_t q = n - 1; q >= 0; --q) {
    if (site[q * stride]) last = q;
    if (last >= 0) {
      const double b = spacing * static_cast<double>(last - q);
      if (b < d[q]) d[q] = b;
    }
    d[q] = d[q] * d[q];
  }
}

// Adds parabola i (vertex at pos(i), height val(i)) to the lower envelope of the parabolas
// y = val + w (x - pos)^2 added so far in increasing pos: v[0..k] are the envelope's parabolas,
// z[j]..z[j+1] the abscissae where v[j] is lowest (k = -1: empty).
template <typename Pos, typename Val>
inline void envelope_push(std::ptrdiff_t i, double w, std::ptrdiff_t* v, double* z, std::ptrdiff_t& k, Pos pos,
                          Val val) {
  if (k < 0) {
    k = 0;
    v[0] = i;
    z[0] = -kInf;
    z[1] = kInf;
    return;
  }
  const double fq = val(i), qq = static_cast<double>(pos(i));
  double s;
  for (;;) {
    const double p = static_cast<double>(pos(v[k]));
    // Abscissa where the parabolas rooted at p and q meet.
    s = ((fq - val(v[k])) / w + (qq * qq - p * p)) / (2.0 * (qq - p));
    if (s <= z[k]) {
      --k;  // z[0] = -inf, so k never drops below 0 here.
    } else {
      break;
    }
  }
  ++k;
  v[k] = i;
  z[k] = s;
  z[k + 1] = kInf;
}

// Lower envelope of parabolas: d[q] = min_p f[p] + (spacing * (q - p))^2 for q in [0, n).
// Entries f[p] = +inf are not sites; a line without sites gives d = +inf everywhere.
// v (n ints) and z (n + 1 doubles) are caller-provided scratch; d must not alias f.
inline void lower_envelope_1d(const double* f, double* d, std::ptrdiff_t n, double spacing, std::ptrdiff_t* v,
                              double* z) {
  const double w = spacing * spacing;
  const auto pos = [](std::ptrdiff_t q) { return q; };
  const auto val = [f](std::ptrdiff_t q) { return f[q]; };
  std::ptrdiff_t k = -1;
  for (std::ptrdiff_t q = 0; q < n; ++q) {
    if (f[q] != kInf) envelope_push(q, w, v, z, k, pos, val);
  }
  if (k < 0) {
    for (std::ptrdiff_t q = 0; q < n; ++q) d[q] = kInf;
    return;
  }
  k = 0;
  for (std::ptrdiff_t q = 0; q < n; ++q) {
    const double qq = static_cast<double>(q);
    while (z[k + 1] < qq) ++k;
    const double dq = spacing * (qq - static_cast<double>(v[k]));
    d[q] = f[v[k]] + dq * dq;
  }
}

}  // namespace cufund::esdf
