#include "occupancy_grid.h"

#include <algorithm>
#include <cmath>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "parallel.h"

namespace cufund::esdf {

OccupancyGrid::OccupancyGrid(const GridGeometry& geometry, const SensorModel& model)
    : geometry_(geometry),
      model_(model),
      log_odds_(static_cast<std::size_t>(geometry.shape[0] * geometry.shape[1] * geometry.shape[2]), 0.0f) {}

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
// Bit b of the result: byte p[b] is not zero (b < 64).
inline std::uint64_t byte_mask(const std::uint8_t* p) {
#if defined(__SSE2__)
  const __m128i zero = _mm_setzero_si128();
  std::uint64_t m = 0;
  for (int q = 0; q < 4; ++q) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + 16 * q));
    const auto is_zero = static_cast<unsigned>(_mm_movemask_epi8(_mm_cmpeq_epi8(v, zero)));
    m |= static_cast<std::uint64_t>(~is_zero & 0xFFFFu) << (16 * q);
  }
  return m;
#else
  std::uint64_t m = 0;
  for (int b = 0; b < 64; ++b) m |= static_cast<std::uint64_t>(p[b] != 0) << b;
  return m;
#endif
}
}  // namespace

bool OccupancyGrid::clip(const double* a, const double* b, Clip* c) const {
  const auto& n = geometry_.shape;
  for (int i = 0; i < 3; ++i) {
    c->a[i] = a[i];
    c->d[i] = b[i] - a[i];
  }
  const double* d = c->d;
  // Clip the parameter range [0, 1] of a + t d to the grid box [0, n].
  double t0 = 0.0, t1 = 1.0;
  for (int i = 0; i < 3; ++i) {
    const double hi = static_cast<double>(n[i]);
    if (d[i] == 0.0) {
      if (a[i] < 0.0 || a[i] >= hi) return false;
      continue;
    }
    double lo_t = (0.0 - a[i]) / d[i], hi_t = (hi - a[i]) / d[i];
    if (lo_t > hi_t) std::swap(lo_t, hi_t);
    t0 = std::max(t0, lo_t);
    t1 = std::min(t1, hi_t);
  }
  if (t0 > t1) return false;
  for (int i = 0; i < 3; ++i) {
    const auto clampi = [&](double u) { return std::clamp(static_cast<Index>(std::floor(u)), Index{0}, n[i] - 1); };
    c->cur[i] = clampi(a[i] + t0 * d[i]);
    c->end[i] = clampi(t1 >= 1.0 ? b[i] : a[i] + t1 * d[i]);
  }
  c->t0 = t0;
  c->t1 = t1;
  return true;
}

template <typename Visit>
void OccupancyGrid::traverse(const Clip& c, bool skip_end, Visit&& visit) const {
  const auto& n = geometry_.shape;
  const double* a = c.a;
  const double* d = c.d;
  const double t1 = c.t1;
  const Index* cur = c.cur;
  const Index* end = c.end;
  Index step[3];
  double t_max[3], t_delta[3];
  for (int i = 0; i < 3; ++i) {
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
  // Exactly |end - cur| steps along each axis, so the walk ends on `end` and never leaves the grid
  // whatever the rounding of the crossing times: an axis whose steps are used up is never chosen again
  // (its crossing time becomes +inf). The axis to step is the one crossing next, ties to the later axis
  // pair: x if tx < ty and tx < tz, else y if ty < tz, else z. (With branches the chain a step carries
  // is one addition; branch-free versions (selects, table lookups, SSE2 masks) were 1.1-1.7x slower.)
  const double inf = std::numeric_limits<double>::infinity();
  Index rx = std::abs(end[0] - cur[0]), ry = std::abs(end[1] - cur[1]), rz = std::abs(end[2] - cur[2]);
  Index steps = rx + ry + rz;
  // An axis with steps left must compare below the used-up ones (+inf), even if its first crossing time
  // overflowed (a sub-voxel extent along it, so a single step: it is +inf after that one).
  const double big = std::numeric_limits<double>::max();
  double tx = rx ? std::min(t_max[0], big) : inf, ty = ry ? std::min(t_max[1], big) : inf,
         tz = rz ? std::min(t_max[2], big) : inf;
  const double dx = t_delta[0], dy = t_delta[1], dz = t_delta[2];
  const Index lx = step[0] * n[1] * n[2], ly = step[1] * n[2], lz = step[2];
  Index index = (cur[0] * n[1] + cur[1]) * n[2] + cur[2];
  for (; steps > 0; --steps) {
    visit(index);
    if (tx < ty && tx < tz) {
      index += lx;
      tx = --rx ? tx + dx : inf;
    } else if (ty < tz) {
      index += ly;
      ty = --ry ? ty + dy : inf;
    } else {
      index += lz;
      tz = --rz ? tz + dz : inf;
    }
  }
  if (!(skip_end && end_holds_b)) visit(index);
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

bool OccupancyGrid::beam_end(const double* p, const double* origin_W, double* e, Index* voxel, ScanStats* stats) const {
  const auto& g = geometry_;
  const double dx = p[0] - origin_W[0], dy = p[1] - origin_W[1], dz = p[2] - origin_W[2];
  const double r = std::sqrt(dx * dx + dy * dy + dz * dz);
  bool hit = true;
  if (r > model_.max_range) {
    ++stats->beyond_range;
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
    e[i] = (e[i] - g.origin_W[i]) / g.resolution;  // to voxel units
    const double u = std::floor(e[i]);
    inside = inside && u >= 0.0 && u < static_cast<double>(g.shape[i]);
    ijk[i] = inside ? static_cast<Index>(u) : 0;
  }
  if (hit && !inside) {
    ++stats->outside;
    hit = false;
  }
  *voxel = (ijk[0] * g.shape[1] + ijk[1]) * g.shape[2] + ijk[2];
  return hit;
}

void OccupancyGrid::mark(const Scan& scan, ScanMarks* m, int nthreads) const {
  const auto& g = geometry_;
  const Index n = scan.n;
  const double* p_W = scan.p_W;
  const double* origin_W = scan.origin_W.data();
  const bool merge = model_.merge_beams;
  ScanStats& stats = m->stats;
  stats = ScanStats{};
  stats.points = n;
  const std::size_t words = (log_odds_.size() + 63) / 64;
  if (m->hit.size() != words) {
    m->hit.assign(words, 0u);
    m->free.assign(64 * words, 0u);
    m->free_end.assign(merge ? words : 0, 0u);
  }
  std::uint8_t* free = m->free.data();
  double origin_v[3];  // the sensor in voxel units
  for (int i = 0; i < 3; ++i) origin_v[i] = (origin_W[i] - g.origin_W[i]) / g.resolution;
  auto& free_ends = m->free_ends;
  free_ends.clear();
  // The beam of point k, or false when it is not cast: a non-finite point, a segment missing the grid,
  // or with merge_beams a beam ending in the same voxel as an earlier one of this scan (hits once per
  // voxel; a free beam's end is the last voxel it reaches inside the grid). Hits are recorded here.
  const auto beam = [&](Index k, Clip* c, bool* hit) {
    const double* p = p_W + 3 * k;
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
      ++stats.nan_points;
      return false;
    }
    double e[3];
    Index i;
    *hit = beam_end(p, origin_W, e, &i, &stats);
    if (*hit && test_and_set(m->hit, i) && merge) return false;
    if (!clip(origin_v, e, c)) return false;
    if (merge && !*hit) {
      const Index j = (c->end[0] * g.shape[1] + c->end[1]) * g.shape[2] + c->end[2];
      if (test_and_set(m->free_end, j)) return false;
      free_ends.push_back(j);
    }
    ++stats.beams;
    return true;
  };
  // The voxels a beam crosses are marked one byte each (a plain store: no read-modify-write chain
  // through memory while a beam walks within one word); the set does not depend on the order.
  if (nthreads <= 1) {
    for (Index k = 0; k < n; ++k) {
      Clip c;
      bool hit;
      if (beam(k, &c, &hit)) traverse(c, hit, [free](Index i) { free[i] = 1; });
    }
  } else {
    // Beams on several threads: first which to cast (in order, as above), then the walks, whose byte
    // stores to shared lines are atomic (relaxed: only the final set matters).
    auto& use = m->use;
    use.assign(static_cast<std::size_t>(n), 0);
    for (Index k = 0; k < n; ++k) {
      Clip c;
      bool hit;
      if (beam(k, &c, &hit)) use[static_cast<std::size_t>(k)] = hit ? 2 : 1;
    }
    parallel_chunks(n, 256, nthreads, [&](Index begin, Index end, Index) {
      for (Index k = begin; k < end; ++k) {
        const std::uint8_t u = use[static_cast<std::size_t>(k)];
        if (!u) continue;
        double e[3];
        Index i;
        ScanStats ignored;
        beam_end(p_W + 3 * k, origin_W, e, &i, &ignored);
        Clip c;
        clip(origin_v, e, &c);
        traverse(c, u == 2, [free](Index v) { __atomic_store_n(free + v, std::uint8_t{1}, __ATOMIC_RELAXED); });
      }
    });
  }
  for (Index i : free_ends) clear(m->free_end, i);
}

void OccupancyGrid::apply_marks(ScanMarks* const* marks, int count, std::vector<Index>* flipped,
                                std::vector<std::uint8_t>* flipped_state, int nthreads) {
  const auto words = static_cast<Index>(marks[0]->hit.size());
  const Index chunk = chunk_size(words, nthreads, 1024);
  const Index chunks = (words + chunk - 1) / chunk;
  if (static_cast<Index>(chunk_flips_.size()) < chunks) chunk_flips_.resize(static_cast<std::size_t>(chunks));
  const float hit_add = model_.log_odds_hit, miss_add = model_.log_odds_miss;
  const float lo = model_.log_odds_min, hi = model_.log_odds_max, occ = model_.log_odds_occupied;
  float* l = log_odds_.data();
  // Voxel ranges in parallel; within a word, the scans in order (hit: +hit up to the upper bound, else
  // crossed: +miss down to the lower bound), so each voxel sees the same sequence as scan by scan.
  parallel_chunks(words, chunk, nthreads, [&](Index begin, Index end, Index c) {
    ChunkFlips& out = chunk_flips_[static_cast<std::size_t>(c)];
    out.index.clear();
    out.state.clear();
    out.hit_voxels.assign(static_cast<std::size_t>(count), 0);
    out.free_voxels.assign(static_cast<std::size_t>(count), 0);
    std::vector<std::uint64_t> free_words(static_cast<std::size_t>(count));
    for (Index w = begin; w < end; ++w) {
      std::uint64_t touched = 0;
      for (int j = 0; j < count; ++j) {
        std::uint8_t* f = marks[j]->free.data() + 64 * w;
        free_words[j] = byte_mask(f);
        if (free_words[j]) std::fill(f, f + 64, std::uint8_t{0});
        touched |= marks[j]->hit[static_cast<std::size_t>(w)] | free_words[j];
      }
      if (!touched) continue;
      float* lw = l + 64 * w;
      std::uint64_t before = 0;
      for (std::uint64_t b = touched; b != 0; b &= b - 1) {
        const int bit = __builtin_ctzll(b);
        before |= static_cast<std::uint64_t>(lw[bit] > occ) << bit;
      }
      for (int j = 0; j < count; ++j) {
        std::uint64_t& hw = marks[j]->hit[static_cast<std::size_t>(w)];
        const std::uint64_t h = hw, f = free_words[j] & ~hw;
        hw = 0;
        out.hit_voxels[static_cast<std::size_t>(j)] += __builtin_popcountll(h);
        out.free_voxels[static_cast<std::size_t>(j)] += __builtin_popcountll(f);
        for (std::uint64_t b = h; b != 0; b &= b - 1) {
          float& v = lw[__builtin_ctzll(b)];
          v = std::min(v + hit_add, hi);
        }
        for (std::uint64_t b = f; b != 0; b &= b - 1) {
          float& v = lw[__builtin_ctzll(b)];
          v = std::max(v + miss_add, lo);
        }
      }
      for (std::uint64_t b = touched; b != 0; b &= b - 1) {
        const int bit = __builtin_ctzll(b);
        const bool after = lw[bit] > occ;
        if (after != static_cast<bool>((before >> bit) & 1u)) {
          out.index.push_back(64 * w + bit);
          out.state.push_back(after ? 1 : 0);
        }
      }
    }
  });
  for (Index c = 0; c < chunks; ++c) {
    const ChunkFlips& f = chunk_flips_[static_cast<std::size_t>(c)];
    flipped->insert(flipped->end(), f.index.begin(), f.index.end());
    flipped_state->insert(flipped_state->end(), f.state.begin(), f.state.end());
    for (int j = 0; j < count; ++j) {
      marks[j]->stats.hit_voxels += f.hit_voxels[static_cast<std::size_t>(j)];
      marks[j]->stats.free_voxels += f.free_voxels[static_cast<std::size_t>(j)];
    }
  }
}

ScanStats OccupancyGrid::insert_scan(const double* p_W, Index n, const double* origin_W, std::vector<Index>* flipped,
                                     std::vector<std::uint8_t>* flipped_state, int nthreads) {
  return insert_scans({Scan{p_W, n, {origin_W[0], origin_W[1], origin_W[2]}}}, flipped, flipped_state, nthreads);
}

ScanStats OccupancyGrid::insert_scans(const std::vector<Scan>& scans, std::vector<Index>* flipped,
                                      std::vector<std::uint8_t>* flipped_state, int nthreads) {
  ScanStats total;
  if (scans.empty()) return total;
  const int nt = resolve_threads(nthreads);
  // Scans traversed at a time: one per thread, a few per thread for balance, marks within ~64 MB.
  const std::size_t words = (log_odds_.size() + 63) / 64;
  const std::size_t by_memory = std::max<std::size_t>(1, (std::size_t{64} << 20) / (80 * words + 1));
  const auto group =
      static_cast<std::size_t>(std::min<std::size_t>({scans.size(), static_cast<std::size_t>(4 * nt), by_memory}));
  if (marks_.size() < group) marks_.resize(group);
  std::vector<ScanMarks*> marks(group);
  for (std::size_t k = 0; k < group; ++k) marks[k] = &marks_[k];
  const std::size_t before = flipped->size();
  for (std::size_t first = 0; first < scans.size(); first += group) {
    const auto count = static_cast<Index>(std::min(group, scans.size() - first));
    if (count == 1) {
      mark(scans[first], marks[0], nt);  // one scan: its beams on every thread
    } else {
      parallel_chunks(count, 1, nt, [&](Index k, Index, Index) {
        mark(scans[first + static_cast<std::size_t>(k)], marks[static_cast<std::size_t>(k)], 1);
      });
    }
    apply_marks(marks.data(), static_cast<int>(count), flipped, flipped_state, nt);
    for (Index k = 0; k < count; ++k) {
      const ScanStats& s = marks[static_cast<std::size_t>(k)]->stats;
      total.points += s.points;
      total.nan_points += s.nan_points;
      total.outside += s.outside;
      total.beyond_range += s.beyond_range;
      total.beams += s.beams;
      total.hit_voxels += s.hit_voxels;
      total.free_voxels += s.free_voxels;
    }
  }
  if (scans.size() > group) {
    // Several groups: a voxel may have flipped in more than one. Keep each voxel once, when its state
    // differs from before the batch (the opposite of its first flip), in ascending order.
    std::vector<std::pair<Index, std::uint8_t>> f;
    f.reserve(flipped->size() - before);
    for (std::size_t k = before; k < flipped->size(); ++k) f.emplace_back((*flipped)[k], (*flipped_state)[k]);
    std::stable_sort(f.begin(), f.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
    flipped->resize(before);
    flipped_state->resize(before);
    for (std::size_t k = 0; k < f.size(); ++k) {
      if (k && f[k].first == f[k - 1].first) continue;
      const bool initial = f[k].second == 0;
      if (occupied(f[k].first) != initial) {
        flipped->push_back(f[k].first);
        flipped_state->push_back(initial ? 0 : 1);
      }
    }
  }
  total.flipped_voxels = static_cast<Index>(flipped->size() - before);
  return total;
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
