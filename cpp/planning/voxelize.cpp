#include "voxelize.h"

#include <algorithm>
#include <cmath>

namespace cufund::planning {

using Index = std::ptrdiff_t;

namespace {

inline void sub(const double* a, const double* b, double* out) {
  for (int i = 0; i < 3; ++i) out[i] = a[i] - b[i];
}
inline void cross(const double* a, const double* b, double* out) {
  out[0] = a[1] * b[2] - a[2] * b[1];
  out[1] = a[2] * b[0] - a[0] * b[2];
  out[2] = a[0] * b[1] - a[1] * b[0];
}
inline double dot(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

}  // namespace

bool triangle_box_overlap(const double* c, const double* hs, const double* v0, const double* v1, const double* v2) {
  double v[3][3];
  sub(v0, c, v[0]);
  sub(v1, c, v[1]);
  sub(v2, c, v[2]);
  double e[3][3];
  sub(v[1], v[0], e[0]);
  sub(v[2], v[1], e[1]);
  sub(v[0], v[2], e[2]);
  // A tolerance relative to the box keeps touching contacts (a face on a voxel boundary) overlapping
  // despite rounding; it can only add voxels, never drop one.
  const double eps = 1e-9 * (hs[0] + hs[1] + hs[2]);
  // 1. The box's face normals (the triangle's bounding box against the box).
  for (int a = 0; a < 3; ++a) {
    const double mn = std::min({v[0][a], v[1][a], v[2][a]}), mx = std::max({v[0][a], v[1][a], v[2][a]});
    if (mn > hs[a] + eps || mx < -hs[a] - eps) return false;
  }
  // 2. The triangle's normal.
  double n[3];
  cross(e[0], e[1], n);
  const double r_n = hs[0] * std::fabs(n[0]) + hs[1] * std::fabs(n[1]) + hs[2] * std::fabs(n[2]);
  const double scale_n = std::sqrt(dot(n, n));
  if (std::fabs(dot(n, v[0])) > r_n + eps * scale_n) return false;
  // 3. The nine cross products of box axes and triangle edges.
  for (int a = 0; a < 3; ++a) {
    double axis_unit[3] = {0.0, 0.0, 0.0};
    axis_unit[a] = 1.0;
    for (int k = 0; k < 3; ++k) {
      double ax[3];
      cross(axis_unit, e[k], ax);
      const double len = std::sqrt(dot(ax, ax));
      if (len == 0.0) continue;  // edge parallel to the box axis: covered by the other tests
      const double p0 = dot(ax, v[0]), p1 = dot(ax, v[1]), p2 = dot(ax, v[2]);
      const double r = hs[0] * std::fabs(ax[0]) + hs[1] * std::fabs(ax[1]) + hs[2] * std::fabs(ax[2]);
      if (std::min({p0, p1, p2}) > r + eps * len || std::max({p0, p1, p2}) < -r - eps * len) return false;
    }
  }
  return true;
}

std::vector<Index> voxelize_triangles(const esdf::GridGeometry& g, const double* vertices, Index /*n_vertices*/,
                                      const std::int64_t* triangles, Index n_triangles) {
  std::vector<Index> out;
  const double h = g.resolution;
  const double hs[3] = {0.5 * h, 0.5 * h, 0.5 * h};
  for (Index t = 0; t < n_triangles; ++t) {
    const double* p[3] = {vertices + 3 * triangles[3 * t], vertices + 3 * triangles[3 * t + 1],
                          vertices + 3 * triangles[3 * t + 2]};
    Index lo[3], hi[3];
    bool empty = false;
    for (int a = 0; a < 3; ++a) {
      const auto sa = static_cast<std::size_t>(a);
      const double mn = std::min({p[0][a], p[1][a], p[2][a]}), mx = std::max({p[0][a], p[1][a], p[2][a]});
      const double bound = static_cast<double>(g.shape[sa]) + 2.0;  // clamp before casting to an integer
      const double u0 = std::clamp((mn - g.origin_W[sa]) / h, -2.0, bound);
      const double u1 = std::clamp((mx - g.origin_W[sa]) / h, -2.0, bound);
      // One voxel of slack each side: the exact test decides (closed boxes, a face on a boundary
      // touches the voxels on both sides whatever the rounding of u).
      lo[a] = std::max<Index>(0, static_cast<Index>(std::floor(u0)) - 1);
      hi[a] = std::min<Index>(g.shape[sa] - 1, static_cast<Index>(std::floor(u1)) + 1);
      if (u1 < -1.0 || u0 > static_cast<double>(g.shape[sa]) + 1.0 || lo[a] > hi[a]) empty = true;
    }
    if (empty) continue;
    for (Index i = lo[0]; i <= hi[0]; ++i) {
      for (Index j = lo[1]; j <= hi[1]; ++j) {
        for (Index k = lo[2]; k <= hi[2]; ++k) {
          const double c[3] = {g.origin_W[0] + (static_cast<double>(i) + 0.5) * h,
                               g.origin_W[1] + (static_cast<double>(j) + 0.5) * h,
                               g.origin_W[2] + (static_cast<double>(k) + 0.5) * h};
          if (triangle_box_overlap(c, hs, p[0], p[1], p[2])) out.push_back((i * g.shape[1] + j) * g.shape[2] + k);
        }
      }
    }
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace cufund::planning
