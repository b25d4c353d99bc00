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

// |cos incidence| of ray i on its hit, in float as the intensity has always been computed.
float incidence_cos(const CastFrame& cast, std::size_t i) {
  const float* ray = cast.rays.data() + 6 * i;
  const float* nrm = cast.normals.data() + 3 * i;
  return std::fabs((nrm[0] * ray[3] + nrm[1] * ray[4]) + nrm[2] * ray[5]);
}

// Reflectivity of ray i's hit: 1 without reflectivities (and for an unknown geometry, reported by cast_frame).
double hit_reflectivity(const RangeModel& model, const CastFrame& cast, std::size_t i) {
  if (!model.reflectivity || cast.geometry[i] >= model.n_reflectivity) return 1.0;
  return model.reflectivity[cast.geometry[i]];
}

// The true range ray i reports before noise: a mixed pixel between its surface and a neighbour's across a
// depth edge of its channel, or its own (see RangeModel::mixed_draw). rank: position of each ray in cast.order.
double mixed_range(const FrameRays& rays, const RangeModel& model, const CastFrame& cast,
                   const std::vector<std::uint32_t>& rank, std::size_t i) {
  const double r = cast.t_hit[i];
  if (!(model.mixed_draw[2 * i] < model.mixed_probability)) return r;
  const std::size_t k = rank[i];
  double best = 0.0, r_other = r;
  for (const std::size_t kk : {k - 1, k + 1}) {  // k - 1 wraps to SIZE_MAX at k = 0: out of range
    if (kk >= rays.n) continue;
    const std::size_t j = cast.order[kk];
    if (rays.channel[j] != rays.channel[i]) continue;
    const double rj = cast.t_hit[j];
    if (!std::isfinite(rj)) continue;  // a miss: no second surface in the footprint
    const double jump = std::fabs(rj - r);
    if (jump > model.mixed_edge && jump > best) best = jump, r_other = rj;
  }
  if (best == 0.0) return r;
  return r + model.mixed_draw[2 * i + 1] * (r_other - r);
}

}  // namespace

double range_sigma(const RangeModel& model, double r, double c) {
  const double inc = model.incidence_noise * (1.0 / std::max(c, kMinIncidenceCos) - 1.0);
  return (model.noise_std + model.noise_per_m * r) * (1.0 + inc);
}

double detection_range(const RangeModel& model, double rho, double c) {
  return model.max_range_at_10pct * std::sqrt(std::max(rho * c, 0.0) / 0.1);
}

double detection_probability(const RangeModel& model, double r, double rho, double c) {
  const double r_max = detection_range(model, rho, c);
  if (r <= r_max) return 1.0;
  const double width = model.detection_softness * r_max;
  if (!(width > 0.0)) return 0.0;
  const double x = (r - r_max) / width;
  if (x >= 1.0) return 0.0;
  return 1.0 - x * x * (3.0 - 2.0 * x);
}

double intensity_sigma(const RangeModel& model, double r, double rho, double c) {
  if (!std::isfinite(model.max_range_at_10pct)) return model.intensity_noise;
  const double r_max = detection_range(model, rho, c);
  const double q = r_max > 0.0 ? r / r_max : 1.0;
  return model.intensity_noise * (1.0 + q * q);
}

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
  channel_order(rays.channel, n, out.order);
  RayHits hits{out.t_hit.data(), out.geometry.data(), nullptr, nullptr, out.normals.data()};
  scene.cast_rays_ordered(out.rays.data(), n, out.order.data(), hits, nthreads);
  out.returns.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double r = out.t_hit[i];
    if (!(r >= model.range_min && r <= model.range_max)) continue;
    if (model.keep_draw && !(model.keep_draw[i] >= model.dropout)) continue;
    if (model.reflectivity && out.geometry[i] >= model.n_reflectivity && out.bad_geometry == kInvalidId) {
      out.bad_geometry = out.geometry[i];
    }
    if (model.detect_draw && !(model.detect_draw[i] < detection_probability(model, r, hit_reflectivity(model, out, i),
                                                                            incidence_cos(out, i)))) {
      continue;
    }
    out.returns.push_back(static_cast<std::uint32_t>(i));
  }
}

void write_returns(const FrameRays& rays, const RangeModel& model, const CastFrame& cast, const FrameReturns& out) {
  // The arithmetic follows the NumPy model it replaced, operation for operation (the same bits); the terms
  // added since (noise_z, mixed pixels, jitter, intensity noise) only run when their draws are given.
  const std::size_t m = cast.returns.size();
  thread_local std::vector<std::uint32_t> rank;
  if (model.mixed_draw) {
    rank.resize(rays.n);
    for (std::size_t k = 0; k < rays.n; ++k) rank[cast.order[k]] = static_cast<std::uint32_t>(k);
  }
  for (std::size_t j = 0; j < m; ++j) {
    const std::size_t i = cast.returns[j];
    const double r_true = cast.t_hit[i];
    const float cos_inc = incidence_cos(cast, i);
    const double r_base = model.mixed_draw ? mixed_range(rays, model, cast, rank, i) : r_true;
    double r = r_base;
    if (model.noise_z) {
      r = std::max(r_base + model.noise_z[i] * range_sigma(model, r_true, cos_inc), 0.0);
    } else if (model.noise) {
      r = std::max(r_base + model.noise[i], 0.0);
    }
    const double* d = rays.d_L + 3 * i;
    const float* ray = cast.rays.data() + 6 * i;
    for (int c = 0; c < 3; ++c) {
      out.points_L[3 * j + c] = static_cast<float>(d[c] * r);
      out.points_W[3 * j + c] =
          static_cast<float>(static_cast<double>(ray[c]) + static_cast<double>(ray[3 + c]) * r_true);
    }
    if (model.intensity_z) {
      const double rho = hit_reflectivity(model, cast, i);
      const double s = intensity_sigma(model, r_true, rho, cos_inc);
      const double value = std::clamp(rho * static_cast<double>(cos_inc) * (1.0 + s * model.intensity_z[i]), 0.0, 1.0);
      if (model.reflectivity) {
        out.intensity[j] = value;
      } else {
        out.intensity_f32[j] = static_cast<float>(value);
      }
    } else if (model.reflectivity) {
      out.intensity[j] = std::clamp(model.reflectivity[cast.geometry[i]] * static_cast<double>(cos_inc), 0.0, 1.0);
    } else {
      out.intensity_f32[j] = std::clamp(cos_inc, 0.0f, 1.0f);
    }
    out.dt[j] = model.dt_noise ? std::clamp(rays.t[i] + model.dt_noise[i], 0.0, model.dt_max) : rays.t[i];
    out.ranges[j] = r;
    out.channel[j] = rays.channel[i];
    out.object_ids[j] = cast.geometry[i];
  }
}

}  // namespace cufund::lidar
