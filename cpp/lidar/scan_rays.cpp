#include "scan_rays.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace cufund::lidar {

bool scan_rays(const double* d_L, const double* t, std::size_t n, const double* knot_t, const double* knot_p,
               const double* knot_q, std::size_t k, float* rays) {
  if (k < 2) return false;
  // Per segment: the angle between its end quaternions, for slerp weights.
  std::vector<double> theta(k - 1), inv_sin(k - 1);
  for (std::size_t s = 0; s + 1 < k; ++s) {
    const double* a = knot_q + 4 * s;
    const double* b = a + 4;
    const double dot = std::clamp(a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3], -1.0, 1.0);
    theta[s] = std::acos(dot);
    const double sn = std::sin(theta[s]);
    inv_sin[s] = sn > 1e-9 ? 1.0 / sn : 0.0;  // 0: nearly equal rotations, fall back to lerp
  }
  std::size_t seg = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double ti = std::clamp(t[i], knot_t[0], knot_t[k - 1]);
    // Rays come mostly in time order: walk the segment index instead of searching.
    while (seg + 2 < k && ti >= knot_t[seg + 1]) ++seg;
    while (seg > 0 && ti < knot_t[seg]) --seg;
    const double u = (ti - knot_t[seg]) / (knot_t[seg + 1] - knot_t[seg]);
    double w0 = 1.0 - u, w1 = u;
    if (inv_sin[seg] > 0.0) {
      w0 = std::sin((1.0 - u) * theta[seg]) * inv_sin[seg];
      w1 = std::sin(u * theta[seg]) * inv_sin[seg];
    }
    const double* qa = knot_q + 4 * seg;
    const double* qb = qa + 4;
    double q[4];
    double norm = 0.0;
    for (int c = 0; c < 4; ++c) {
      q[c] = w0 * qa[c] + w1 * qb[c];
      norm += q[c] * q[c];
    }
    norm = 1.0 / std::sqrt(norm);
    const double w = q[0] * norm, x = q[1] * norm, y = q[2] * norm, z = q[3] * norm;
    const double* d = d_L + 3 * i;
    // v' = v + 2 w (q x v) + 2 q x (q x v)
    const double cx = y * d[2] - z * d[1], cy = z * d[0] - x * d[2], cz = x * d[1] - y * d[0];
    const double rx = d[0] + 2.0 * (w * cx + y * cz - z * cy);
    const double ry = d[1] + 2.0 * (w * cy + z * cx - x * cz);
    const double rz = d[2] + 2.0 * (w * cz + x * cy - y * cx);
    const double* pa = knot_p + 3 * seg;
    const double* pb = pa + 3;
    float* r = rays + 6 * i;
    for (int c = 0; c < 3; ++c) r[c] = static_cast<float>((1.0 - u) * pa[c] + u * pb[c]);
    r[3] = static_cast<float>(rx);
    r[4] = static_cast<float>(ry);
    r[5] = static_cast<float>(rz);
  }
  return true;
}

}  // namespace cufund::lidar
