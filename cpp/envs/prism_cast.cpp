#include "prism_cast.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rotation.h"
#include "target_clones.h"
#include "thread_pool.h"

namespace cufund::envs {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

bool finite(double v) { return std::isfinite(v); }

struct Buffers {
  std::vector<float> dx, dy, dz, best, tn, tf;
  void resize(std::size_t r) {
    if (dx.size() >= r) return;
    for (auto* v : {&dx, &dy, &dz, &best, &tn, &tf}) v->resize(r);
  }
};

// [lo, hi] of the pixel indices whose centres may see a box with sensor-frame corners c_S (8 x 3); false when
// the box cannot be in view. The box is clipped to x >= kNear first (its corners there and where its edges cross
// x = kNear); only a surface closer than kNear along the optical axis (a camera inside a trunk's skin) could be
// missed, where Embree reports the nearest hit even below range_min.
constexpr double kNear = 1e-6;

bool pixel_span(const double c_S[8][3], const Pinhole& cam, int* u0, int* u1, int* v0, int* v1) {
  double umin = kInf, umax = -kInf, vmin = kInf, vmax = -kInf;
  auto add = [&](double x, double y, double z) {
    const double u = -y / x * cam.focal + 0.5 * cam.width - 0.5;  // pixel centre u + 0.5 = x_n f + W / 2, x_n = -y / x
    const double v = -z / x * cam.focal + 0.5 * cam.height - 0.5;
    umin = std::min(umin, u), umax = std::max(umax, u), vmin = std::min(vmin, v), vmax = std::max(vmax, v);
  };
  int front = 0;
  for (int k = 0; k < 8; ++k) {
    if (c_S[k][0] >= kNear) {
      add(c_S[k][0], c_S[k][1], c_S[k][2]);
      ++front;
    }
  }
  if (front == 0) return false;
  if (front < 8) {
    for (int a = 0; a < 8; ++a) {
      for (int bit = 1; bit < 8; bit <<= 1) {
        const int b = a | bit;
        if (b == a) continue;
        const double xa = c_S[a][0], xb = c_S[b][0];
        if ((xa >= kNear) == (xb >= kNear)) continue;
        const double f = (kNear - xa) / (xb - xa);
        add(kNear, c_S[a][1] + f * (c_S[b][1] - c_S[a][1]), c_S[a][2] + f * (c_S[b][2] - c_S[a][2]));
      }
    }
  }
  // A thousandth of a pixel of margin for rounding: the clipping, not the span, decides the hits.
  const double lo_u = std::floor(umin - 1e-3), hi_u = std::ceil(umax + 1e-3);
  const double lo_v = std::floor(vmin - 1e-3), hi_v = std::ceil(vmax + 1e-3);
  if (hi_u < 0 || lo_u > cam.width - 1 || hi_v < 0 || lo_v > cam.height - 1) return false;
  *u0 = static_cast<int>(std::max(0.0, lo_u));
  *u1 = static_cast<int>(std::min<double>(cam.width - 1, hi_u));
  *v0 = static_cast<int>(std::max(0.0, lo_v));
  *v1 = static_cast<int>(std::min<double>(cam.height - 1, hi_v));
  return true;
}

// Compiled for several instruction sets, picked at load time (the ray loops are the SIMD lanes).
CUFUND_TARGET_CLONES
void cast_one(const PrismScene& s, const double* p_WS, const double* q_WS, const float* d_S, const Pinhole& cam,
              double reach, float* out, Buffers& b) {
  const int W = cam.width, H = cam.height;
  const std::size_t r = static_cast<std::size_t>(W) * H;
  b.resize(r);
  double R[9];
  quat_to_rotation(q_WS, R);  // R_WS, as lidar::batch_cast's rays use it
  const float o[3] = {static_cast<float>(p_WS[0]), static_cast<float>(p_WS[1]), static_cast<float>(p_WS[2])};
  const double od[3] = {o[0], o[1], o[2]};
  // World directions, column-major (index u * H + v), rounded as lidar::batch_cast's rays are.
  for (int v = 0; v < H; ++v) {
    for (int u = 0; u < W; ++u) {
      const float* d = d_S + 3 * (static_cast<std::size_t>(v) * W + u);
      const double x = d[0], y = d[1], z = d[2];
      const std::size_t j = static_cast<std::size_t>(u) * H + v;
      b.dx[j] = static_cast<float>(R[0] * x + R[1] * y + R[2] * z);
      b.dy[j] = static_cast<float>(R[3] * x + R[4] * y + R[5] * z);
      b.dz[j] = static_cast<float>(R[6] * x + R[7] * y + R[8] * z);
      b.best[j] = kInf;
    }
  }
  float* const best = b.best.data();
  const float* const dx = b.dx.data();
  const float* const dy = b.dy.data();
  const float* const dz = b.dz.data();
  for (std::size_t j = 0; j < s.rects(); ++j) {
    const float num = static_cast<float>(s.rect_z[j] - od[2]);
    const float x0 = static_cast<float>(s.rect_x0[j]), x1 = static_cast<float>(s.rect_x1[j]);
    const float y0 = static_cast<float>(s.rect_y0[j]), y1 = static_cast<float>(s.rect_y1[j]);
    for (std::size_t k = 0; k < r; ++k) {
      const float t = num / dz[k];
      const float x = o[0] + t * dx[k], y = o[1] + t * dy[k];
      const bool hit = t >= 0.0f && x >= x0 && x <= x1 && y >= y0 && y <= y1;
      best[k] = (hit && t < best[k]) ? t : best[k];
    }
  }
  float* const tn = b.tn.data();
  float* const tf = b.tf.data();
  for (std::size_t j = 0; j < s.prisms(); ++j) {
    // Culled by distance: the box's nearest point beyond every ray's reach.
    const double ex = std::max({s.box_x0[j] - od[0], 0.0, od[0] - s.box_x1[j]});
    const double ey = std::max({s.box_y0[j] - od[1], 0.0, od[1] - s.box_y1[j]});
    const double ez = std::max({s.zmin[j] - od[2], 0.0, od[2] - s.zmax[j]});
    if (ex * ex + ey * ey + ez * ez > reach * reach) continue;
    double c_S[8][3];
    for (int k = 0; k < 8; ++k) {
      const double w[3] = {((k & 1) ? s.box_x1[j] : s.box_x0[j]) - od[0], ((k & 2) ? s.box_y1[j] : s.box_y0[j]) - od[1],
                           ((k & 4) ? s.zmax[j] : s.zmin[j]) - od[2]};
      for (int a = 0; a < 3; ++a) c_S[k][a] = R[a] * w[0] + R[3 + a] * w[1] + R[6 + a] * w[2];  // R^T w
    }
    int u0, u1, v0, v1;
    if (!pixel_span(c_S, cam, &u0, &u1, &v0, &v1)) continue;
    const float zn0 = static_cast<float>(s.zmin[j] - od[2]), zn1 = static_cast<float>(s.zmax[j] - od[2]);
    for (int u = u0; u <= u1; ++u) {
      const std::size_t k0 = static_cast<std::size_t>(u) * H + v0, k1 = static_cast<std::size_t>(u) * H + v1 + 1;
      // The z slab first: entry and exit along each ray.
      for (std::size_t k = k0; k < k1; ++k) {
        const float ta = zn0 / dz[k], tb = zn1 / dz[k];
        const bool flat = dz[k] == 0.0f;
        const bool inside = zn0 <= 0.0f && zn1 >= 0.0f;
        tn[k] = flat ? (inside ? -kInf : kInf) : std::min(ta, tb);
        tf[k] = flat ? (inside ? kInf : -kInf) : std::max(ta, tb);
      }
      for (std::size_t p = s.plane_begin[j]; p < s.plane_begin[j + 1]; ++p) {
        const float nx = s.nx[p], ny = s.ny[p];
        const float num =
            static_cast<float>(s.c[p] - (static_cast<double>(nx) * od[0] + static_cast<double>(ny) * od[1]));
        for (std::size_t k = k0; k < k1; ++k) {
          // Float products are exact in double: den carries one rounding, not the cancellation of its terms
          // (a ray along a face: its entry and exit then order as in exact arithmetic up to float rounding).
          const float den = static_cast<float>(static_cast<double>(nx) * dx[k] + static_cast<double>(ny) * dy[k]);
          const float t = num / den;
          tn[k] = den < 0.0f ? std::max(tn[k], t) : tn[k];
          tf[k] = den > 0.0f ? std::min(tf[k], t) : ((den == 0.0f && num < 0.0f) ? -kInf : tf[k]);
        }
      }
      for (std::size_t k = k0; k < k1; ++k) {
        // Entering at tn (or, from inside, leaving at tf: Embree reports the exit face then).
        const float t = tn[k] >= 0.0f ? tn[k] : tf[k];
        const bool hit = tn[k] <= tf[k] && tf[k] >= 0.0f && t < best[k];
        best[k] = hit ? t : best[k];
      }
    }
  }
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) out[static_cast<std::size_t>(v) * W + u] = best[static_cast<std::size_t>(u) * H + v];
}

}  // namespace

PrismSceneCheck check_scene(const PrismScene& s) {
  const std::size_t n = s.prisms();
  const std::size_t planes = s.nx.size();
  if (s.plane_begin.size() != n + 1 || s.plane_begin[0] != 0 || s.plane_begin[n] != planes || s.ny.size() != planes ||
      s.c.size() != planes || s.zmax.size() != n || s.box_x0.size() != n || s.box_x1.size() != n ||
      s.box_y0.size() != n || s.box_y1.size() != n) {
    return {PrismSceneStatus::kBadPrism, 0};
  }
  for (std::size_t j = 0; j < n; ++j) {
    if (s.plane_begin[j + 1] <= s.plane_begin[j] || !finite(s.zmin[j]) || !finite(s.zmax[j]) ||
        !(s.zmin[j] <= s.zmax[j]) || !finite(s.box_x0[j]) || !finite(s.box_x1[j]) || !finite(s.box_y0[j]) ||
        !finite(s.box_y1[j]) || !(s.box_x0[j] <= s.box_x1[j]) || !(s.box_y0[j] <= s.box_y1[j])) {
      return {PrismSceneStatus::kBadPrism, j};
    }
    for (std::size_t p = s.plane_begin[j]; p < s.plane_begin[j + 1]; ++p) {
      if (!finite(s.nx[p]) || !finite(s.ny[p]) || !finite(s.c[p]) || (s.nx[p] == 0.0f && s.ny[p] == 0.0f)) {
        return {PrismSceneStatus::kBadPrism, j};
      }
    }
  }
  const std::size_t m = s.rects();
  if (s.rect_x0.size() != m || s.rect_x1.size() != m || s.rect_y0.size() != m || s.rect_y1.size() != m) {
    return {PrismSceneStatus::kBadRect, 0};
  }
  for (std::size_t j = 0; j < m; ++j) {
    if (!finite(s.rect_z[j]) || !finite(s.rect_x0[j]) || !finite(s.rect_x1[j]) || !finite(s.rect_y0[j]) ||
        !finite(s.rect_y1[j]) || !(s.rect_x0[j] <= s.rect_x1[j]) || !(s.rect_y0[j] <= s.rect_y1[j])) {
      return {PrismSceneStatus::kBadRect, j};
    }
  }
  return {};
}

std::size_t first_non_pinhole_ray(const float* d_S, const Pinhole& cam) {
  const std::size_t r = static_cast<std::size_t>(cam.width) * static_cast<std::size_t>(cam.height);
  constexpr float kTol = 4 * std::numeric_limits<float>::epsilon();
  // Each column's -x_n and each row's -y_n once (checked on every call: no division per pixel).
  thread_local std::vector<float> col, row;
  col.resize(static_cast<std::size_t>(cam.width));
  row.resize(static_cast<std::size_t>(cam.height));
  for (int u = 0; u < cam.width; ++u) col[u] = static_cast<float>(-((u + 0.5 - cam.width / 2.0) / cam.focal));
  for (int v = 0; v < cam.height; ++v) row[v] = static_cast<float>(-((v + 0.5 - cam.height / 2.0) / cam.focal));
  // written as <= so that a NaN is refused too; a row's test is one branch-free loop, its bad ray found after
  auto near = [&](float d, float e) { return std::abs(d - e) <= kTol * std::max(1.0f, std::abs(e)); };
  for (int v = 0; v < cam.height; ++v) {
    const float* d = d_S + 3 * static_cast<std::size_t>(v) * cam.width;
    bool ok = true;
    for (int u = 0; u < cam.width; ++u)
      ok &= near(d[3 * u], 1.0f) & near(d[3 * u + 1], col[u]) & near(d[3 * u + 2], row[v]);
    if (ok) continue;
    for (int u = 0; u < cam.width; ++u) {
      if (!(near(d[3 * u], 1.0f) && near(d[3 * u + 1], col[u]) && near(d[3 * u + 2], row[v]))) {
        return static_cast<std::size_t>(v) * cam.width + u;
      }
    }
  }
  return r;
}

lidar::BatchResult prism_depth_cast(const PrismScene& scene, const lidar::SensorPoses& poses, const float* d_S,
                                    const Pinhole& cam, const lidar::BatchRangeModel& model, float* out, int nthreads) {
  const std::size_t r = static_cast<std::size_t>(cam.width) * static_cast<std::size_t>(cam.height);
  const lidar::BatchResult res = lidar::check_sensor_input(poses, d_S, r);
  if (res.status != lidar::BatchStatus::kOk) return res;
  // A hit farther than range_max (in units of the longest direction) reads miss_value: prisms beyond are culled.
  double dmax = 0.0;
  for (std::size_t k = 0; k < r; ++k) {
    const double x = d_S[3 * k], y = d_S[3 * k + 1], z = d_S[3 * k + 2];
    dmax = std::max(dmax, std::sqrt(x * x + y * y + z * z));
  }
  const double reach = static_cast<double>(model.range_max) * dmax * (1.0 + 1e-6) + 1e-6;
  ForkSafeSection no_fork;
  parallel_chunks(static_cast<std::ptrdiff_t>(poses.n), 1, nthreads, [&](std::size_t i, std::size_t, std::size_t) {
    thread_local Buffers buffers;
    float* t = out + r * i;
    cast_one(scene, poses.p_WS + 3 * i, poses.q_WS + 4 * i, d_S, cam, reach, t, buffers);
    lidar::apply_range_model(model, i, t, r);
  });
  return {};
}

}  // namespace cufund::envs
