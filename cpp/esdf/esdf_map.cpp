#include "esdf_map.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "parallel.h"

namespace cufund::esdf {

EsdfMap::EsdfMap(const GridGeometry& geometry, const SensorModel& model, const EsdfOptions& options)
    : grid_(geometry, model), options_(options), outside_(geometry.shape) {
  if (options.signed_distance) inside_.emplace(geometry.shape);
  recompute();
}

std::vector<std::int32_t> EsdfMap::inside_squared() const {
  return inside_ ? inside_->squared_distance() : outside_.squared_distance();
}

void EsdfMap::recompute() {
  const Index n = grid_.size();
  std::vector<std::uint8_t> occ(static_cast<std::size_t>(n));
  for (Index i = 0; i < n; ++i) occ[static_cast<std::size_t>(i)] = grid_.occupied(i) ? 1 : 0;
  outside_.reset(occ.data(), options_.nthreads);
  if (inside_) {
    for (auto& o : occ) o = o ? 0 : 1;
    inside_->reset(occ.data(), options_.nthreads);
  }
}

EsdfUpdateStats EsdfMap::apply(const std::vector<Index>& flipped, const std::vector<std::uint8_t>& state) {
  const auto start = std::chrono::steady_clock::now();
  EsdfUpdateStats stats;
  stats.outside = outside_.update(flipped, state, options_.nthreads);
  if (inside_) {
    std::vector<std::uint8_t> free_state(state.size());
    for (std::size_t k = 0; k < state.size(); ++k) free_state[k] = state[k] ? 0 : 1;
    stats.inside = inside_->update(flipped, free_state, options_.nthreads);
  }
  stats.field_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

EsdfUpdateStats EsdfMap::insert_scan(const double* p_W, Index n, const double* origin_W) {
  std::vector<Index> flipped;
  std::vector<std::uint8_t> state;
  const auto start = std::chrono::steady_clock::now();
  const ScanStats scan = grid_.insert_scan(p_W, n, origin_W, &flipped, &state, options_.nthreads);
  const double raycast = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EsdfUpdateStats stats = apply(flipped, state);
  stats.scan = scan;
  stats.raycast_seconds = raycast;
  return stats;
}

EsdfUpdateStats EsdfMap::insert_scans(const std::vector<Scan>& scans) {
  std::vector<Index> flipped;
  std::vector<std::uint8_t> state;
  const auto start = std::chrono::steady_clock::now();
  const ScanStats scan = grid_.insert_scans(scans, &flipped, &state, options_.nthreads);
  const double raycast = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EsdfUpdateStats stats = apply(flipped, state);
  stats.scan = scan;
  stats.raycast_seconds = raycast;
  return stats;
}

EsdfUpdateStats EsdfMap::set_occupied(const std::vector<Index>& index, const std::vector<std::uint8_t>& value) {
  std::vector<Index> flipped;
  std::vector<std::uint8_t> state;
  grid_.set_occupied(index, value, &flipped, &state);
  return apply(flipped, state);
}

EsdfUpdateStats EsdfMap::set_log_odds(const float* values) {
  std::vector<Index> flipped;
  std::vector<std::uint8_t> state;
  grid_.set_log_odds(values, &flipped, &state);
  return apply(flipped, state);
}

double EsdfMap::voxel_distance(Index i) const {
  const double inf = std::numeric_limits<double>::infinity();
  const double h = grid_.geometry().resolution;
  if (inside_ && grid_.occupied(i)) {
    const std::int32_t s = inside_->squared_distance_at(i);
    return s == IncrementalEdt::kNoSite ? -inf : -std::sqrt(static_cast<double>(s)) * h;
  }
  const std::int32_t s = outside_.squared_distance_at(i);
  return s == IncrementalEdt::kNoSite ? inf : std::sqrt(static_cast<double>(s)) * h;
}

void EsdfMap::query(const double* p_W, Index n, double* distance, double* grad_W) const {
  const auto& g = grid_.geometry();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const int nt = resolve_threads(options_.nthreads);
  parallel_chunks(n, chunk_size(n, nt, 2048), n > 4096 ? nt : 1, [&](Index begin, Index end, Index) {
    for (Index k = begin; k < end; ++k) {
      const double* p = p_W + 3 * k;
      double* gk = grad_W ? grad_W + 3 * k : nullptr;
      if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
        distance[k] = nan;
        if (gk) gk[0] = gk[1] = gk[2] = nan;
        continue;
      }
      Index i0[3];
      double t[3], dt[3];  // fraction along each axis and d(fraction)/d(p) (0 when clamped)
      for (int a = 0; a < 3; ++a) {
        const Index na = g.shape[static_cast<std::size_t>(a)];
        const double u = (p[a] - g.origin_W[static_cast<std::size_t>(a)]) / g.resolution - 0.5;
        if (na == 1) {
          i0[a] = 0;
          t[a] = 0.0;
          dt[a] = 0.0;
          continue;
        }
        const Index c =
            std::clamp(static_cast<Index>(std::floor(std::clamp(u, -1.0, static_cast<double>(na)))), Index{0}, na - 2);
        i0[a] = c;
        const double f = u - static_cast<double>(c);
        if (f < 0.0 || f > 1.0) {
          t[a] = f < 0.0 ? 0.0 : 1.0;
          dt[a] = 0.0;
        } else {
          t[a] = f;
          dt[a] = 1.0 / g.resolution;
        }
      }
      // Corner values c[dx][dy][dz].
      double c[2][2][2];
      bool finite = true;
      for (int dx = 0; dx < 2; ++dx) {
        for (int dy = 0; dy < 2; ++dy) {
          for (int dz = 0; dz < 2; ++dz) {
            const Index ix = std::min(i0[0] + dx, g.shape[0] - 1), iy = std::min(i0[1] + dy, g.shape[1] - 1),
                        iz = std::min(i0[2] + dz, g.shape[2] - 1);
            c[dx][dy][dz] = voxel_distance((ix * g.shape[1] + iy) * g.shape[2] + iz);
            finite = finite && std::isfinite(c[dx][dy][dz]);
          }
        }
      }
      if (!finite) {
        distance[k] = c[0][0][0];
        if (gk) gk[0] = gk[1] = gk[2] = 0.0;
        continue;
      }
      const double tx = t[0], ty = t[1], tz = t[2];
      // Interpolate along z, then y, then x.
      double cz[2][2], dcz[2][2];
      for (int dx = 0; dx < 2; ++dx) {
        for (int dy = 0; dy < 2; ++dy) {
          cz[dx][dy] = c[dx][dy][0] + tz * (c[dx][dy][1] - c[dx][dy][0]);
          dcz[dx][dy] = c[dx][dy][1] - c[dx][dy][0];
        }
      }
      const double cy0 = cz[0][0] + ty * (cz[0][1] - cz[0][0]);
      const double cy1 = cz[1][0] + ty * (cz[1][1] - cz[1][0]);
      distance[k] = cy0 + tx * (cy1 - cy0);
      if (gk) {
        const double dy0 = cz[0][1] - cz[0][0], dy1 = cz[1][1] - cz[1][0];
        const double dz0 = dcz[0][0] + ty * (dcz[0][1] - dcz[0][0]);
        const double dz1 = dcz[1][0] + ty * (dcz[1][1] - dcz[1][0]);
        gk[0] = (cy1 - cy0) * dt[0];
        gk[1] = (dy0 + tx * (dy1 - dy0)) * dt[1];
        gk[2] = (dz0 + tx * (dz1 - dz0)) * dt[2];
      }
    }
  });
}

}  // namespace cufund::esdf
