#include "lidar_frame.h"

#include "scan_rays.h"
#include "thread_pool.h"

#include <algorithm>
#include <cmath>

namespace cufund::lidar {

namespace {

// Rays per work item when building rays (each item re-derives the knots' slerp angles: K acos).
constexpr std::ptrdiff_t kBuildChunk = 4096;

// A permutation of [0, n) grouping the rays by channel (ascending), in firing order within a channel:
// consecutive rays of one laser sweep a continuous path, so 8 of them make a narrow packet.
void channel_order(const std::int32_t* channel, std::size_t n, std::vector<std::uint32_t>& order) {
  order.resize(n);
  if (n == 0) return;
  const auto [lo_it, hi_it] = std::minmax_element(channel, channel + n);
  const std::int64_t lo = *lo_it, span = static_cast<std::int64_t>(*hi_it) - lo + 1;
  if (span > static_cast<std::int64_t>(4 * n + 1024)) {  // sparse channel numbers: a stable sort
    for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<std::uint32_t>(i);
    std::stable_sort(order.begin(), order.end(),
                     [&](std::uint32_t a, std::uint32_t b) { return channel[a] < channel[b]; });
    return;
  }
  std::vector<std::uint32_t> start(static_cast<std::size_t>(span) + 1, 0);
  for (std::size_t i = 0; i < n; ++i) ++start[static_cast<std::size_t>(channel[i] - lo) + 1];
  for (std::size_t c = 1; c < start.size(); ++c) start[c] += start[c - 1];
  for (std::size_t i = 0; i < n; ++i)
    order[start[static_cast<std::size_t>(channel[i] - lo)]++] = static_cast<std::uint32_t>(i);
}

}  // namespace

void cast_frame(const RaycastScene& scene, const FrameRays& rays, double t0, const FrameKnots& knots,
                const RangeModel& model, int nthreads, CastFrame& out) {
  const std::size_t n = rays.n;
  out.rays.resize(6 * n);
  out.t_hit.resize(n);
  out.normals.resize(3 * n);
  out.geometry.resize(n);
  out.returns.clear();
  out.bad_geometry = kInvalidId;
  if (n == 0) return;
  parallel_chunks(static_cast<std::ptrdiff_t>(n), kBuildChunk, nthreads,
                  [&](std::ptrdiff_t begin, std::ptrdiff_t end, std::ptrdiff_t) {
                    double t_abs[kBuildChunk];
                    for (std::ptrdiff_t i = begin; i < end; ++i) t_abs[i - begin] = t0 + rays.t[i];
                    scan_rays(rays.d_L + 3 * begin, t_abs, static_cast<std::size_t>(end - begin), knots.t, knots.p,
                              knots.q, knots.k, out.rays.data() + 6 * begin);
                  });
  thread_local std::vector<std::uint32_t> order;
  channel_order(rays.channel, n, order);
  RayHits hits{out.t_hit.data(), out.geometry.data(), nullptr, nullptr, out.normals.data()};
  scene.cast_rays_ordered(out.rays.data(), n, order.data(), hits, nthreads);
  out.returns.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double r = out.t_hit[i];
    if (!(r >= model.range_min && r <= model.range_max)) continue;
    if (model.keep_draw && !(model.keep_draw[i] >= model.dropout)) continue;
    if (model.reflectivity && out.geometry[i] >= model.n_reflectivity && out.bad_geometry == kInvalidId) {
      out.bad_geometry = out.geometry[i];
    }
    out.returns.push_back(static_cast<std::uint32_t>(i));
  }
}

void write_returns(const FrameRays& rays, const RangeModel& model, const CastFrame& cast, const FrameReturns& out) {
  // The arithmetic follows the NumPy model it replaced, operation for operation (the same bits).
  const std::size_t m = cast.returns.size();
  for (std::size_t j = 0; j < m; ++j) {
    const std::size_t i = cast.returns[j];
    const double r_true = cast.t_hit[i];
    const double r = model.noise ? std::max(r_true + model.noise[i], 0.0) : r_true;
    const double* d = rays.d_L + 3 * i;
    const float* ray = cast.rays.data() + 6 * i;
    const float* nrm = cast.normals.data() + 3 * i;
    for (int c = 0; c < 3; ++c) {
      out.points_L[3 * j + c] = static_cast<float>(d[c] * r);
      out.points_W[3 * j + c] =
          static_cast<float>(static_cast<double>(ray[c]) + static_cast<double>(ray[3 + c]) * r_true);
    }
    const float cos_inc = std::fabs((nrm[0] * ray[3] + nrm[1] * ray[4]) + nrm[2] * ray[5]);
    if (model.reflectivity) {
      out.intensity[j] = std::clamp(model.reflectivity[cast.geometry[i]] * static_cast<double>(cos_inc), 0.0, 1.0);
    } else {
      out.intensity_f32[j] = std::clamp(cos_inc, 0.0f, 1.0f);
    }
    out.dt[j] = rays.t[i];
    out.ranges[j] = r;
    out.channel[j] = rays.channel[i];
    out.object_ids[j] = cast.geometry[i];
  }
}

}  // namespace cufund::lidar
