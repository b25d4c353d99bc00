#include "occupancy_grid.h"

#include <algorithm>
#include <cmath>

#include "parallel.h"

namespace cufund::esdf {

OccupancyGrid::OccupancyGrid(const GridGeometry& geometry, const SensorModel& model)
    : geometry_(geometry),
      model_(model),
      log_odds_(static_cast<std::size_t>(geometry.shape[0] * geometry.shape[1] * geometry.shape[2]), 0.0f),
      hit_bits_((log_odds_.size() + 63) / 64, 0u),
      free_bits_(hit_bits_.size(), 0u) {}

namespace {
inline bool test_and_set(std::vector<std::uint64_t>& bits, std::ptrdiff_t i) {
  std::uint64_t& w = bits[static_cast<std::size_t>(i >> 6)];
  const std::uint64_t b = std::uint64_t{1} << (i & 63);
  const bool was = (w & b) != 0;
  w |= b;
  return was;
}
inline void clear(std::vector<std::uint64_t>& bits, std::ptrdiff_t i) {
  bits[static_cast<std::size_t>(i >> 6)] &= ~(std::uint64_t{1} << (i & 63));
}
// Sets bit i; safe against other threads setting bits of the same word. Voxels near the sensor are
// crossed by most beams: a plain (atomic) load skips the locked write, and the cache-line ping-pong
// between threads, once the bit is set.
inline void atomic_set(std::vector<std::uint64_t>& bits, std::ptrdiff_t i) {
  std::uint64_t* w = &bits[static_cast<std::size_t>(i >> 6)];
  const std::uint64_t b = std::uint64_t{1} << (i & 63);
  if (!(__atomic_load_n(w, __ATOMIC_RELAXED) & b)) __atomic_fetch_or(w, b, __ATOMIC_RELAXED);
}
}  // namespace

template <typename Visit>
void OccupancyGrid::traverse(const double* a_W, const double* b_W, bool skip_end, Visit&& visit) const {
  const auto& n = geometry_.shape;
  double a[3], b[3], d[3];
  for (int i = 0; i < 3; ++i) {
    a[i] = (a_W[i] - geometry_.origin_W[i]) / geometry_.resolution;
    b[i] = (b_W[i] - geometry_.origin_W[i]) / geometry_.resolution;
    d[i] = b[i] - a[i];
  }
  // Clip the parameter range [0, 1] of a + t d to the grid box [0, n].
  double t0 = 0.0, t1 = 1.0;
  for (int i = 0; i < 3; ++i) {
    const double hi = static_cast<double>(n[i]);
    if (d[i] == 0.0) {
      if (a[i] < 0.0 || a[i] >= hi) return;
      continue;
    }
    double lo_t = (0.0 - a[i]) / d[i], hi_t = (hi - a[i]) / d[i];
    if (lo_t > hi_t) std::swap(lo_t, hi_t);
    t0 = std::max(t0, lo_t);
    t1 = std::min(t1, hi_t);
  }
  if (t0 > t1) return;
  Index cur[3], end[3], step[3];
  double t_max[3], t_delta[3];
  for (int i = 0; i < 3; ++i) {
    const auto clampi = [&](double u) {
      return std::clamp(static_cast<Index>(std::floor(u)), Index{0}, n[i] - 1);
    };
    cur[i] = clampi(a[i] + t0 * d[i]);
    end[i] = clampi(t1 >= 1.0 ? b[i] : a[i] + t1 * d[i]);
    if (d[i] > 0.0) {
      step[i] = 1;
      t_max[i] = (static_cast<double>(cur[i] + 1) - a[i]) / d[i];
      t_delta[i] = 1.0 / d[i];
    } else if (d[i] < 0.0) {
      step[i] = -1;
      t_max[i] = (static_cast<double>(cur[i]) - a[i]) / d[i];
      t_delta[i] = -1.0 / d[i];
    } else {
      step[i] = 0;
      t_max[i] = std::numeric_limits<double>::infinity();
      t_delta[i] = 0.0;
    }
  }
  // The end voxel holds b only when b is inside the grid, i.e. the segment was not cut at t = 1.
  const bool end_holds_b = t1 >= 1.0;
  // Bound on the number of steps, so rounding can never make the walk run away.
  Index budget = std::abs(end[0] - cur[0]) + std::abs(end[1] - cur[1]) + std::abs(end[2] - cur[2]) + 1;
  // The axis to step is data dependent: chosen with masks rather than branches (a mispredicted
  // branch per voxel would dominate the walk), on scalars so nothing goes through memory. Same
  // choice as min(t_max) with ties to the later axis pair: x if tx < ty and tx < tz, else y if
  // ty < tz, else z.
  double tx = t_max[0], ty = t_max[1], tz = t_max[2];
  Index cx = cur[0], cy = cur[1], cz = cur[2];
  const Index sx = step[0], sy = step[1], sz = step[2];
  const Index lx = sx * n[1] * n[2], ly = sy * n[2], lz = sz;
  Index index = (cx * n[1] + cy) * n[2] + cz;
  for (;;) {
    const bool at_end = cx == end[0] && cy == end[1] && cz == end[2];
    if (!(at_end && skip_end && end_holds_b)) visit(index);
    if (at_end || --budget <= 0) return;
    const bool x_first = tx < ty;
    const bool bx = x_first & (tx < tz);
    const bool by = !x_first & (ty < tz);
    const bool bz = !(bx | by);
    const double t_next = bx ? tx : (by ? ty : tz);
    if (t_next > t1) return;
    cx += bx ? sx : 0;
    cy += by ? sy : 0;
    cz += bz ? sz : 0;
    if (cx < 0 || cx >= n[0] || cy < 0 || cy >= n[1] || cz < 0 || cz >= n[2]) return;
    index += (bx ? lx : 0) + (by ? ly : 0) + (bz ? lz : 0);
    tx += bx ? t_delta[0] : 0.0;
    ty += by ? t_delta[1] : 0.0;
    tz += bz ? t_delta[2] : 0.0;
  }
}

void OccupancyGrid::set(Index i, float value, std::vector<Index>* flipped, std::vector<std::uint8_t>* state) {
  float& l = log_odds_[static_cast<std::size_t>(i)];
  const bool before = l > model_.log_odds_occupied;
  l = value;
  const bool after = l > model_.log_odds_occupied;
  if (before != after) {
    flipped->push_back(i);
    state->push_back(after ? 1 : 0);
  }
}

void OccupancyGrid::apply(Index i, float delta, bool hit, std::vector<Index>* flipped,
                          std::vector<std::uint8_t>* state) {
  const float l = log_odds_[static_cast<std::size_t>(i)];
  set(i, hit ? std::min(l + delta, model_.log_odds_max) : std::max(l + delta, model_.log_odds_min), flipped, state);
}

ScanStats OccupancyGrid::insert_scan(const double* p_W, Index n, const double* origin_W, std::vector<Index>* flipped,
                                     std::vector<std::uint8_t>* flipped_state, int nthreads) {
  ScanStats stats;
  stats.points = n;
  const auto& g = geometry_;
  const int nt = resolve_threads(nthreads);
  auto& hits = hits_;
  hits.clear();

  // Beam ends first, so that a voxel both hit and crossed in one scan counts as hit only.
  auto& use = use_;
  auto& ends = ends_;
  use.assign(static_cast<std::size_t>(n), 0);
  ends.resize(static_cast<std::size_t>(3 * n));
  for (Index k = 0; k < n; ++k) {
    const double* p = p_W + 3 * k;
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
      ++stats.nan_points;
      continue;
    }
    double* e = ends.data() + 3 * k;
    const double dx = p[0] - origin_W[0], dy = p[1] - origin_W[1], dz = p[2] - origin_W[2];
    const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
    bool hit = true;
    if (r > model_.max_range) {
      ++stats.beyond_range;
      const double s = model_.max_range / r;
      e[0] = origin_W[0] + s * dx;
      e[1] = origin_W[1] + s * dy;
      e[2] = origin_W[2] + s * dz;
      hit = false;
    } else {
      e[0] = p[0];
      e[1] = p[1];
      e[2] = p[2];
    }
    Index ijk[3];
    bool inside = true;
    for (int i = 0; i < 3; ++i) {
      const double u = std::floor((e[i] - g.origin_W[i]) / g.resolution);
      inside = inside && u >= 0.0 && u < static_cast<double>(g.shape[i]);
      ijk[i] = inside ? static_cast<Index>(u) : 0;
    }
    if (hit && !inside) {
      ++stats.outside;
      hit = false;
    }
    use[static_cast<std::size_t>(k)] = hit ? 2 : 1;  // 2: beam with a hit end, 1: free beam
    if (hit) {
      const Index i = (ijk[0] * g.shape[1] + ijk[1]) * g.shape[2] + ijk[2];
      if (!test_and_set(hit_bits_, i)) hits.push_back(i);
    }
  }
  // Beams in parallel: each marks the voxels it crosses in a shared bitset, so the set of free voxels,
  // gathered below in ascending order, does not depend on which thread crossed what. Hit voxels are
  // unmarked afterwards (one pass over the few hits, not a second bitset lookup per step).
  parallel_chunks(n, 256, nt, [&](Index begin, Index end, Index) {
    for (Index k = begin; k < end; ++k) {
      const std::uint8_t u = use[static_cast<std::size_t>(k)];
      if (!u) continue;
      traverse(origin_W, ends.data() + 3 * k, u == 2, [&](Index i) {
        atomic_set(free_bits_, i);
      });
    }
  });
  for (Index i : hits) clear(free_bits_, i);
  for (Index i : hits) clear(hit_bits_, i);
  const std::size_t before = flipped->size();
  for (Index i : hits) apply(i, model_.log_odds_hit, true, flipped, flipped_state);
  // Free voxels: drained from the bitset and updated in parallel over word ranges, each range's flips
  // appended in range order, so the flips come out in ascending voxel order as in a serial pass.
  const auto words = static_cast<Index>(free_bits_.size());
  const Index chunk = chunk_size(words, nt, 4096);
  const Index chunks = (words + chunk - 1) / chunk;
  if (static_cast<Index>(chunk_flips_.size()) < chunks) chunk_flips_.resize(static_cast<std::size_t>(chunks));
  parallel_chunks(words, chunk, nt, [&](Index begin, Index end, Index c) {
    ChunkFlips& out = chunk_flips_[static_cast<std::size_t>(c)];
    out.index.clear();
    out.state.clear();
    out.free_voxels = 0;
    for (Index k = begin; k < end; ++k) {
      std::uint64_t& w = free_bits_[static_cast<std::size_t>(k)];
      for (std::uint64_t b = w; b != 0; b &= b - 1) {
        apply(k * 64 + __builtin_ctzll(b), model_.log_odds_miss, false, &out.index, &out.state);
        ++out.free_voxels;
      }
      w = 0;
    }
  });
  for (Index c = 0; c < chunks; ++c) {
    const ChunkFlips& f = chunk_flips_[static_cast<std::size_t>(c)];
    flipped->insert(flipped->end(), f.index.begin(), f.index.end());
    flipped_state->insert(flipped_state->end(), f.state.begin(), f.state.end());
    stats.free_voxels += f.free_voxels;
  }
  stats.hit_voxels = static_cast<Index>(hits.size());
  stats.flipped_voxels = static_cast<Index>(flipped->size() - before);
  return stats;
}

void OccupancyGrid::set_occupied(const std::vector<Index>& index, const std::vector<std::uint8_t>& value,
                                 std::vector<Index>* flipped, std::vector<std::uint8_t>* flipped_state) {
  for (std::size_t k = 0; k < index.size(); ++k) {
    set(index[k], value[k] ? model_.log_odds_max : model_.log_odds_min, flipped, flipped_state);
  }
}

void OccupancyGrid::set_log_odds(const float* values, std::vector<Index>* flipped,
                                 std::vector<std::uint8_t>* flipped_state) {
  for (Index i = 0; i < size(); ++i) set(i, values[i], flipped, flipped_state);
}

}  // namespace cufund::esdf
