#include "clearance.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace cufund::planning {

using Index = std::ptrdiff_t;

ClearanceMap::ClearanceMap(const esdf::EsdfMap& map)
    : map_(&map), geometry_(map.geometry()), half_diagonal_(0.5 * std::sqrt(3.0) * map.geometry().resolution) {}

ClearanceMap::ClearanceMap(const esdf::GridGeometry& geometry, const double* distances)
    : distances_(distances), geometry_(geometry), half_diagonal_(0.5 * std::sqrt(3.0) * geometry.resolution) {}

bool ClearanceMap::inside(const Vec3& p) const {
  for (int a = 0; a < 3; ++a) {
    const double lo = geometry_.origin_W[static_cast<std::size_t>(a)];
    const double hi = lo + geometry_.resolution * static_cast<double>(geometry_.shape[static_cast<std::size_t>(a)]);
    if (!(p[static_cast<std::size_t>(a)] >= lo && p[static_cast<std::size_t>(a)] <= hi)) return false;  // NaN: false
  }
  return true;
}

Vec3 ClearanceMap::centre(Index i, Index j, Index k) const {
  const double h = geometry_.resolution;
  return {geometry_.origin_W[0] + (static_cast<double>(i) + 0.5) * h,
          geometry_.origin_W[1] + (static_cast<double>(j) + 0.5) * h,
          geometry_.origin_W[2] + (static_cast<double>(k) + 0.5) * h};
}

double ClearanceMap::centre_distance(Index linear) const {
  const double d = map_ ? map_->voxel_distance(linear) : distances_[linear];
  return d > 0.0 ? d : 0.0;  // occupied (signed, negative or -inf): the nearest occupied centre is itself
}

double ClearanceMap::clearance(const Vec3& p) const {
  if (!inside(p)) return -std::numeric_limits<double>::infinity();
  const double h = geometry_.resolution;
  Index lo[3], cnt[3], near[3];
  for (int a = 0; a < 3; ++a) {
    const auto sa = static_cast<std::size_t>(a);
    const Index n = geometry_.shape[sa];
    const double u = (p[sa] - geometry_.origin_W[sa]) / h - 0.5;  // in voxel-centre coordinates
    const Index c = std::clamp(static_cast<Index>(std::floor(u)), Index{0}, std::max<Index>(n - 2, 0));
    lo[a] = c;
    cnt[a] = n >= 2 ? 2 : 1;
    near[a] = (cnt[a] == 2 && u - static_cast<double>(c) > 0.5) ? 1 : 0;  // the corner nearest p first
  }
  const Index ny = geometry_.shape[1], nz = geometry_.shape[2];
  double best = -std::numeric_limits<double>::infinity();
  for (int m = 0; m < 8; ++m) {
    const Index dx = (m >> 2) ^ near[0], dy = ((m >> 1) & 1) ^ near[1], dz = (m & 1) ^ near[2];
    if (dx >= cnt[0] || dy >= cnt[1] || dz >= cnt[2]) continue;
    const Index i = lo[0] + dx, j = lo[1] + dy, k = lo[2] + dz;
    const double d = centre_distance((i * ny + j) * nz + k);
    if (d <= best) continue;                                     // d - |p - c| cannot beat the best
    if (d == std::numeric_limits<double>::infinity()) return d;  // nothing occupied
    const double cx = geometry_.origin_W[0] + (static_cast<double>(i) + 0.5) * h - p[0];
    const double cy = geometry_.origin_W[1] + (static_cast<double>(j) + 0.5) * h - p[1];
    const double cz = geometry_.origin_W[2] + (static_cast<double>(k) + 0.5) * h - p[2];
    best = std::max(best, d - std::sqrt(cx * cx + cy * cy + cz * cz));
  }
  return best - half_diagonal_;
}

bool ClearanceMap::segment_free(const Vec3& p0, const Vec3& p1, double radius) const {
  const Vec3 d{p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
  const double length = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  if (!std::isfinite(length)) return false;
  const double min_step = this->min_step();
  // Trace from both ends towards the middle: a blocked end is found after one query.
  double s0 = 0.0, s1 = length;
  while (true) {
    const Vec3 a{p0[0] + d[0] * (length > 0 ? s0 / length : 0.0), p0[1] + d[1] * (length > 0 ? s0 / length : 0.0),
                 p0[2] + d[2] * (length > 0 ? s0 / length : 0.0)};
    const double ca = clearance(a) - radius;
    if (!(ca >= 0.0)) return false;
    const Vec3 b{p0[0] + d[0] * (length > 0 ? s1 / length : 0.0), p0[1] + d[1] * (length > 0 ? s1 / length : 0.0),
                 p0[2] + d[2] * (length > 0 ? s1 / length : 0.0)};
    const double cb = clearance(b) - radius;
    if (!(cb >= 0.0)) return false;
    // Balls of radius ca around a and cb around b are free (at clearance >= radius).
    if (s1 - s0 <= ca + cb) return true;
    if (ca < min_step || cb < min_step) return false;
    s0 += ca;
    s1 -= cb;
  }
}

double ClearanceMap::segment_min_clearance(const Vec3& p0, const Vec3& p1, double spacing) const {
  const Vec3 d{p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
  const double length = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
  const Index n = std::max<Index>(1, static_cast<Index>(std::ceil(length / spacing)));
  double best = std::numeric_limits<double>::infinity();
  for (Index k = 0; k <= n; ++k) {
    const double s = static_cast<double>(k) / static_cast<double>(n);
    best = std::min(best, clearance({p0[0] + d[0] * s, p0[1] + d[1] * s, p0[2] + d[2] * s}));
  }
  return best;
}

}  // namespace cufund::planning
