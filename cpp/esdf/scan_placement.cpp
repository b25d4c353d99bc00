#include "scan_placement.h"

#include <algorithm>
#include <cmath>

#include "parallel.h"
#include "rotation.h"

namespace cufund::esdf {

namespace {

// Interval i (knots i, i + 1) and fraction s of time t, as interpolate_poses takes them (the last knot
// at or before t, clamped to [0, n - 2]). `*i` on entry is a hint: kept when it is still the interval.
void interval(const PoseKnots& k, double t, std::ptrdiff_t* i, double* s) {
  const std::ptrdiff_t h = *i;
  const bool hint_ok = h >= 0 && h <= k.n - 2 && (h == 0 || k.t[h] <= t) && (h == k.n - 2 || t < k.t[h + 1]);
  if (!hint_ok) {
    const std::ptrdiff_t j = std::upper_bound(k.t, k.t + k.n, t) - k.t - 1;
    *i = std::clamp<std::ptrdiff_t>(j, 0, k.n - 2);
  }
  const double t0 = k.t[*i], t1 = k.t[*i + 1];
  *s = std::clamp((t - t0) / (t1 - t0), 0.0, 1.0);
}

}  // namespace

RigidTransform body_pose_at(const PoseKnots& k, double t) {
  std::ptrdiff_t hint = -1;
  return body_pose_at(k, t, &hint);
}

RigidTransform body_pose_at(const PoseKnots& k, double t, std::ptrdiff_t* hint) {
  RigidTransform T;
  double q[4];
  if (k.n == 1) {
    std::copy(k.p_W, k.p_W + 3, T.t.begin());
    std::copy(k.q_WB, k.q_WB + 4, q);
  } else {
    double s;
    interval(k, t, hint, &s);
    const std::ptrdiff_t i = *hint;
    const double* p0 = k.p_W + 3 * i;
    const double* q0 = k.q_WB + 4 * i;
    const double* q1 = q0 + 4;
    const double dot = q0[0] * q1[0] + q0[1] * q1[1] + q0[2] * q1[2] + q0[3] * q1[3];
    const double sign = dot < 0 ? -1.0 : 1.0;
    for (int a = 0; a < 3; ++a) T.t[a] = (1 - s) * p0[a] + s * p0[a + 3];
    for (int a = 0; a < 4; ++a) q[a] = (1 - s) * q0[a] + s * (sign * q1[a]);
  }
  quat_to_rotation(q, T.R.data());  // normalises q (the interpolated one is off the unit sphere)
  return T;
}

void place_points(const PoseKnots& knots, const RigidTransform& T_BL, const double* points_L, const double* t,
                  std::ptrdiff_t n, double* points_W) {
  // Points come in firing order: the pose is recomputed only when the time changes.
  double last_t = std::nan("");
  std::ptrdiff_t hint = -1;  // points come in firing order: the interval is usually the previous one
  RigidTransform T_WB;
  double R_WL[9] = {}, p_WL[3] = {};
  for (std::ptrdiff_t k = 0; k < n; ++k) {
    if (!(t[k] == last_t)) {
      last_t = t[k];
      T_WB = body_pose_at(knots, t[k], &hint);
      const double* R = T_WB.R.data();
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) {
          R_WL[3 * r + c] = R[3 * r] * T_BL.R[c] + R[3 * r + 1] * T_BL.R[3 + c] + R[3 * r + 2] * T_BL.R[6 + c];
        }
        p_WL[r] = T_WB.t[r] + (R[3 * r] * T_BL.t[0] + R[3 * r + 1] * T_BL.t[1] + R[3 * r + 2] * T_BL.t[2]);
      }
    }
    const double* p = points_L + 3 * k;
    double* o = points_W + 3 * k;
    for (int r = 0; r < 3; ++r) o[r] = p_WL[r] + (R_WL[3 * r] * p[0] + R_WL[3 * r + 1] * p[1] + R_WL[3 * r + 2] * p[2]);
  }
}

std::vector<PlacedFrame> place_frames(const PoseKnots& knots, const RigidTransform& T_BL, const LidarFrame* frames,
                                      std::size_t count, int nthreads) {
  std::vector<PlacedFrame> placed(count);
  parallel_chunks(static_cast<std::ptrdiff_t>(count), 1, resolve_threads(nthreads),
                  [&](std::ptrdiff_t k, std::ptrdiff_t, std::ptrdiff_t) {
                    const LidarFrame& f = frames[k];
                    PlacedFrame& out = placed[static_cast<std::size_t>(k)];
                    out.points_W.resize(static_cast<std::size_t>(3 * f.n));
                    place_points(knots, T_BL, f.points_L, f.t, f.n, out.points_W.data());
                    const RigidTransform T_WB = body_pose_at(knots, f.t_origin);
                    for (int r = 0; r < 3; ++r) {
                      out.origin_W[r] = T_WB.t[r] + T_WB.R[3 * r] * T_BL.t[0] + T_WB.R[3 * r + 1] * T_BL.t[1] +
                                        T_WB.R[3 * r + 2] * T_BL.t[2];
                    }
                  });
  return placed;
}

}  // namespace cufund::esdf
