#include "incremental_edt.h"

#include <algorithm>
#include <cmath>

#include "edt_line.h"
#include "parallel.h"

namespace cufund::esdf {
namespace {

using Index = IncrementalEdt::Index;

inline double to_double(std::int32_t v) { return v == IncrementalEdt::kNoSite ? kInf : static_cast<double>(v); }
// Lower envelopes of integer data are integers, exact in double for any grid that fits in memory.
inline std::int32_t to_int(double v) { return v == kInf ? IncrementalEdt::kNoSite : static_cast<std::int32_t>(v); }

// Full stage-2 passes run on groups of this many neighbouring lines along x, whose outputs share
// cache lines (16 int32 = 64 bytes).
constexpr Index kGroup = 16;
// A stage falls back to a full pass when its changed positions exceed 1/kFullPassFactor of the grid.
constexpr Index kFullPassFactor = 8;
// Lines ahead whose changed inputs and outputs are prefetched: a line's first touch is a cache miss.
constexpr Index kPrefetchLines = 4;

}  // namespace

struct IncrementalEdt::Scratch : LineBuffers {
  // Buffers for `lines` lines of length n handled together (full passes group kGroup lines).
  Scratch(Index lines, Index n) : LineBuffers(lines, n) {}
  std::vector<std::pair<Index, Index>> windows;  // outputs recomputed exactly
  std::vector<Position> grown, shrunk;           // changed inputs: (p, old) / (p, new)
};

IncrementalEdt::IncrementalEdt(const std::array<Index, 3>& shape)
    : shape_(shape),
      sites_(static_cast<std::size_t>(size()), 0),
      g1_(static_cast<std::size_t>(size()), kNoSite),
      g2_(static_cast<std::size_t>(size()), kNoSite),
      g3_(static_cast<std::size_t>(size()), kNoSite),
      merge_slot_(static_cast<std::size_t>(std::max({shape[0] * shape[1], shape[0] * shape[2], shape[1] * shape[2]})),
                  -1) {}

IncrementalEdt::LineView IncrementalEdt::view(int stage, Index line) {
  const Index nx = shape_[0], ny = shape_[1], nz = shape_[2];
  if (stage == 2) {  // input g1[ix][iz][:], output g2[iz][:][ix]
    const Index iz = line / nx, ix = line % nx;
    return {ny, g1_.data() + (ix * nz + iz) * ny, g2_.data() + iz * ny * nx + ix, nx};
  }
  return {nx, g2_.data() + line * nx, g3_.data() + line * nx, 1};  // g2[iz][iy][:] -> g3[iz][iy][:]
}

void IncrementalEdt::column(Index c, std::vector<double>& buf, std::vector<Change>* changed) {
  const Index nx = shape_[0], ny = shape_[1], nz = shape_[2];
  const Index ix = c / ny, iy = c % ny;
  squared_distance_to_sites_1d(sites_.data() + c * nz, 1, nz, 1.0, buf.data());
  for (Index q = 0; q < nz; ++q) {
    const std::int32_t nv = to_int(buf[static_cast<std::size_t>(q)]);
    std::int32_t& old = g1_[static_cast<std::size_t>((ix * nz + q) * ny + iy)];
    if (nv != old) {
      if (changed)
        changed->push_back(
            {q * nx + ix, static_cast<std::int32_t>(iy), std::min(old, nv)});  // stage-2 line (iz = q, ix)
      old = nv;
    }
  }
}

IncrementalEdt::Index IncrementalEdt::full_pass(int stage, int nthreads) {
  const Index nx = shape_[0], ny = shape_[1], nz = shape_[2];
  const Index lines = stage == 2 ? nx * nz : ny * nz;
  const Index group = stage == 2 ? kGroup : 1;
  const Index groups = (lines + group - 1) / group;
  const Index n = stage == 2 ? ny : nx;
  const Index chunk = chunk_size(groups, nthreads, 4);
  const Index chunks = (groups + chunk - 1) / chunk;
  std::vector<Index> totals(static_cast<std::size_t>(chunks), 0);
  parallel_chunks(groups, chunk, nthreads, [&](Index g_begin, Index g_end, Index c) {
    Scratch s(group, n);
    Index& total = totals[static_cast<std::size_t>(c)];
    for (Index g = g_begin; g < g_end; ++g) {
      const Index first = g * group, count = std::min(group, lines - first);
      LineView v[kGroup];
      for (Index j = 0; j < count; ++j) {
        v[j] = view(stage, first + j);
        double* f = s.f.data() + j * n;
        for (Index q = 0; q < n; ++q) f[q] = to_double(v[j].in[q]);
        lower_envelope_1d(f, s.d.data() + j * n, n, 1.0, s.v.data(), s.z.data());
      }
      for (Index q = 0; q < n; ++q) {  // q outer: a group writes whole cache lines
        for (Index j = 0; j < count; ++j) {
          const std::int32_t nv = to_int(s.d[static_cast<std::size_t>(j * n + q)]);
          std::int32_t& o = v[j].out[q * v[j].out_stride];
          if (o != nv) {  // unchanged outputs are not stored: no needless cache-line writes
            ++total;
            o = nv;
          }
        }
      }
    }
  });
  Index total = 0;
  for (Index t : totals) total += t;
  return total;
}

namespace {

// The output positions q in [lo, hi] of a line where the parabola low + (q - p)^2 can reach the old
// output: low + (q - p)^2 <= old(q) (`strict`: < old(q)). Over the whole line they form one interval
// (a parabola under a lower envelope of parabolas of the same curvature, whose difference is
// concave), inside the q with (q - p)^2 <= old(q), which are contiguous around p because sqrt(old)
// is 1-Lipschitz along a line. Walking away from p, the same Lipschitz bound skips q that provably
// fail. Returns (a, b), a > b when empty.
template <typename Old>
std::pair<Index, Index> reach(Index p, Index low, bool strict, Index lo, Index hi, const Old& old) {
  Index a = hi + 1, b = lo - 1;
  const Index start = std::clamp(p, lo, hi);
  bool start_in = false;
  for (const Index dir : {Index{1}, Index{-1}}) {
    if (dir < 0 && b >= a && !start_in) break;  // the interval lies right of the start
    bool found = false;
    for (Index q = dir > 0 ? start : start - 1; q >= lo && q <= hi;) {
      const std::int32_t g = old(q);
      const Index d = q > p ? q - p : p - q;
      const Index c = low + d * d;
      if (g == IncrementalEdt::kNoSite || c < static_cast<Index>(g) || (!strict && c == static_cast<Index>(g))) {
        a = std::min(a, q);
        b = std::max(b, q);
        found = true;
        if (q == start) start_in = true;
        q += dir;
        continue;
      }
      // From here on q moves away from p (or leaves [lo, hi]).
      if (found || d * d > static_cast<Index>(g)) break;  // left the interval, or past the bound
      // Here c >= old(q) = D^2 with d <= D. At d + j, old <= (D + j)^2, so c stays >= old (> old when
      // not strict) while j < gap / (2 (D - d)), gap = c - D^2.
      const double D = std::sqrt(static_cast<double>(g));
      if (D <= static_cast<double>(d)) break;
      const double gap = static_cast<double>(c - static_cast<Index>(g));
      const Index skip = static_cast<Index>(std::floor(gap / (2.0 * (D - static_cast<double>(d))) - 1e-9));
      q += dir * (std::max<Index>(skip, 0) + 1);
    }
  }
  return {a, b};
}

// Sorts intervals and merges the overlapping or adjacent ones, in place.
void merge_intervals(std::vector<std::pair<Index, Index>>& w) {
  std::sort(w.begin(), w.end());
  std::size_t out = 0;
  for (std::size_t i = 0; i < w.size();) {
    Index lo = w[i].first, hi = w[i].second;
    for (++i; i < w.size() && w[i].first <= hi + 1; ++i) hi = std::max(hi, w[i].second);
    w[out++] = {lo, hi};
  }
  w.resize(out);
}

}  // namespace

void IncrementalEdt::update_line(int stage, const LineWork& work, const std::vector<Position>& positions, Scratch& s,
                                 std::vector<Change>* changed, Index* n_changed) {
  const Index nx = shape_[0], ny = shape_[1];
  const LineView v = view(stage, work.line);
  const Index n = v.n;
  const auto old = [&](Index q) { return v.out[q * v.out_stride]; };
  const auto write = [&](Index q, std::int32_t nv) {
    std::int32_t& o = v.out[q * v.out_stride];
    if (o == nv) return;
    ++*n_changed;
    if (changed) {  // stage-3 line (iz, iy = q), position ix
      const Index iz = work.line / nx, ix = work.line % nx;
      changed->push_back({iz * ny + q, static_cast<std::int32_t>(ix), std::min(o, nv)});
    }
    o = nv;
  };
  // An input that grew (its site moved away or vanished) can only raise the outputs it was nearest
  // to: those are recomputed exactly. An input that shrank can only lower outputs, to its own
  // parabola: new(q) = min(old(q), lowest shrunk parabola at q) wherever no input grew.
  auto& grown = s.grown;
  auto& shrunk = s.shrunk;
  grown.clear();
  shrunk.clear();
  for (Index k = work.begin; k < work.end; ++k) {
    const Position& c = positions[static_cast<std::size_t>(k)];
    const std::int32_t now = v.in[c.pos];
    if (c.low < now) {
      grown.push_back({c.pos, c.low});
    } else {
      shrunk.push_back({c.pos, now});
    }
  }
  // Every window is found on the old output, before anything is written.
  auto& exact = s.windows;
  exact.clear();
  for (const Position& c : grown) {
    const auto w = reach(c.pos, c.low, false, 0, n - 1, old);
    if (w.first <= w.second) exact.push_back(w);
  }
  merge_intervals(exact);
  // Only the lower envelope of the shrunk inputs' parabolas can lower an output, each envelope
  // parabola on its own segment (integers q with z[e] < q <= z[e + 1]); walking segments, not every
  // shrunk input's reach, visits each output once. The walks skip the exact windows (recomputed
  // below from their old values) and read nothing but their own segment, which only they write.
  Index top = -1;
  {
    const auto pos = [&](Index j) { return shrunk[static_cast<std::size_t>(j)].pos; };
    const auto val = [&](Index j) { return static_cast<double>(shrunk[static_cast<std::size_t>(j)].low); };
    for (Index j = 0; j < static_cast<Index>(shrunk.size()); ++j)
      envelope_push(j, 1.0, s.v.data(), s.z.data(), top, pos, val);
  }
  const auto lower = [&](const Position& c, Index lo, Index hi) {
    const auto w = reach(c.pos, c.low, true, lo, hi, old);
    for (Index q = w.first; q <= w.second; ++q) write(q, static_cast<std::int32_t>(c.low + (q - c.pos) * (q - c.pos)));
  };
  std::size_t x = 0;  // first exact window not left of the current segment
  for (Index e = 0; e <= top; ++e) {
    const double z0 = s.z[static_cast<std::size_t>(e)], z1 = s.z[static_cast<std::size_t>(e + 1)];
    Index lo = z0 < 0.0 ? 0 : static_cast<Index>(std::floor(z0)) + 1;
    const Index hi = z1 >= static_cast<double>(n - 1) ? n - 1 : static_cast<Index>(std::floor(z1));
    const Position& c = shrunk[static_cast<std::size_t>(s.v[static_cast<std::size_t>(e)])];
    while (x < exact.size() && exact[x].second < lo) ++x;
    for (std::size_t y = x; lo <= hi; ++y) {
      if (y == exact.size() || exact[y].first > hi) {
        lower(c, lo, hi);
        break;
      }
      if (lo < exact[y].first) lower(c, lo, exact[y].first - 1);
      lo = exact[y].second + 1;
    }
  }

  for (const auto& [lo, hi] : exact) {
    // Input window: every site that can be nearest to some q in [lo, hi]. Start from the old
    // distances and widen until provably enough: a site outside [wlo, whi] is at least
    // (q - wlo + 1) or (whi + 1 - q) away from q.
    Index wlo = lo, whi = hi;
    for (Index q = lo; q <= hi && (wlo > 0 || whi < n - 1); ++q) {
      const std::int32_t g = old(q);
      const Index r = g == kNoSite ? n : static_cast<Index>(std::ceil(std::sqrt(static_cast<double>(g))));
      wlo = std::max(Index{0}, std::min(wlo, q - r));
      whi = std::min(n - 1, std::max(whi, q + r));
    }
    for (;;) {
      const Index m = whi - wlo + 1;
      for (Index q = wlo; q <= whi; ++q) s.f[static_cast<std::size_t>(q - wlo)] = to_double(v.in[q]);
      lower_envelope_1d(s.f.data(), s.d.data(), m, 1.0, s.v.data(), s.z.data());
      bool enough = true;
      for (Index q = lo; q <= hi && enough; ++q) {
        const double r = s.d[static_cast<std::size_t>(q - wlo)];
        const double left = static_cast<double>(q - wlo + 1), right = static_cast<double>(whi + 1 - q);
        enough = !((wlo > 0 && r > left * left) || (whi < n - 1 && r > right * right));
      }
      if (enough) break;
      wlo = std::max(Index{0}, wlo - m);  // some distance grew past the window: widen both sides
      whi = std::min(n - 1, whi + m);
    }
    for (Index q = lo; q <= hi; ++q) write(q, to_int(s.d[static_cast<std::size_t>(q - wlo)]));
  }
}

void IncrementalEdt::prefetch_line(int stage, const LineWork& work, const std::vector<Position>& positions) {
  const LineView v = view(stage, work.line);
  for (Index k = work.begin; k < work.end; ++k) __builtin_prefetch(v.in + positions[static_cast<std::size_t>(k)].pos);
  if (v.out_stride == 1) {  // the walks from the changed positions roam the line: fetch all of it
    for (Index q = 0; q < v.n; q += 16) __builtin_prefetch(v.out + q, 1);
  } else {
    for (Index k = work.begin; k < work.end; ++k) {
      __builtin_prefetch(v.out + positions[static_cast<std::size_t>(k)].pos * v.out_stride, 1);
    }
  }
}

void IncrementalEdt::merge(Changes& changes, Work& w) {
  w.lines.clear();
  // Count per line, then bucket the positions by line.
  for (const auto& list : changes) {
    for (const Change& c : list) {
      Index& slot = merge_slot_[static_cast<std::size_t>(c.line)];
      if (slot < 0) {
        slot = static_cast<Index>(w.lines.size());
        w.lines.push_back({c.line, 0, 0});
      }
      ++w.lines[static_cast<std::size_t>(slot)].end;
    }
  }
  std::sort(w.lines.begin(), w.lines.end(), [](const LineWork& a, const LineWork& b) { return a.line < b.line; });
  Index offset = 0;
  for (std::size_t j = 0; j < w.lines.size(); ++j) {
    LineWork& l = w.lines[j];
    merge_slot_[static_cast<std::size_t>(l.line)] = static_cast<Index>(j);
    l.begin = offset;
    offset += l.end;
    l.end = l.begin;  // fill cursor
  }
  w.positions.resize(static_cast<std::size_t>(offset));
  for (auto& list : changes) {
    for (const Change& c : list) {
      LineWork& l = w.lines[static_cast<std::size_t>(merge_slot_[static_cast<std::size_t>(c.line)])];
      w.positions[static_cast<std::size_t>(l.end++)] = {c.pos, c.low};
    }
    list.clear();
  }
  for (const LineWork& l : w.lines) merge_slot_[static_cast<std::size_t>(l.line)] = -1;
  // Sort each line's positions; a repeated position keeps its lowest value (the compacted tail of a
  // bucket is left unused).
  for (LineWork& l : w.lines) {
    auto b = w.positions.begin() + l.begin, e = w.positions.begin() + l.end;
    std::sort(b, e,
              [](const Position& x, const Position& y) { return x.pos < y.pos || (x.pos == y.pos && x.low < y.low); });
    l.end = l.begin + (std::unique(b, e, [](const Position& x, const Position& y) { return x.pos == y.pos; }) - b);
  }
}

std::vector<std::int32_t> IncrementalEdt::squared_distance() const {
  std::vector<std::int32_t> out(static_cast<std::size_t>(size()));
  for (Index i = 0; i < size(); ++i) out[static_cast<std::size_t>(i)] = squared_distance_at(i);
  return out;
}

void IncrementalEdt::reset(const std::uint8_t* sites, int nthreads) {
  for (Index i = 0; i < size(); ++i) sites_[static_cast<std::size_t>(i)] = sites[i] ? 1 : 0;
  recompute(nthreads);
}

void IncrementalEdt::recompute(int nthreads) {
  const int nt = resolve_threads(nthreads);
  const Index nx = shape_[0], ny = shape_[1], nz = shape_[2];
  parallel_chunks(nx * ny, chunk_size(nx * ny, nt, 256), nt, [&](Index begin, Index end, Index) {
    std::vector<double> buf(static_cast<std::size_t>(nz));
    for (Index c = begin; c < end; ++c) column(c, buf, nullptr);
  });
  full_pass(2, nt);
  full_pass(3, nt);
}

void IncrementalEdt::update_slices(const Work& work, int nthreads, Index* x_lines, Index* n_changed) {
  const Index nx = shape_[0], ny = shape_[1];
  const Index longest = std::max({shape_[0], shape_[1], shape_[2]});
  // Stage-2 lines are numbered iz * nx + ix and sorted: each slice's lines form one run.
  std::vector<std::pair<Index, Index>> runs;
  for (Index k = 0; k < static_cast<Index>(work.lines.size()); ++k) {
    if (runs.empty() || work.lines[static_cast<std::size_t>(k)].line / nx !=
                            work.lines[static_cast<std::size_t>(runs.back().first)].line / nx) {
      runs.emplace_back(k, k);
    }
    runs.back().second = k + 1;
  }
  const Index n_runs = static_cast<Index>(runs.size());
  std::vector<Index> lines_done(static_cast<std::size_t>(n_runs), 0), changed(static_cast<std::size_t>(n_runs), 0);
  // Several slices per work item, so their buffers are allocated once per item, not per slice.
  parallel_chunks(n_runs, chunk_size(n_runs, nthreads, 1), nthreads, [&](Index r_begin, Index r_end, Index) {
    Scratch s(1, longest);
    std::vector<Change> out;  // the slice's stage-2 output changes = its stage-3 input changes
    Work slice;               // the same, bucketed by stage-3 line
    std::vector<Index> start(static_cast<std::size_t>(ny + 1));
    for (Index r = r_begin; r < r_end; ++r) {
      const auto [first, last] = runs[static_cast<std::size_t>(r)];
      const Index iz = work.lines[static_cast<std::size_t>(first)].line / nx;
      out.clear();
      Index stage2_changed = 0;
      for (Index k = first; k < last; ++k) {
        if (k + kPrefetchLines < last)
          prefetch_line(2, work.lines[static_cast<std::size_t>(k + kPrefetchLines)], work.positions);
        update_line(2, work.lines[static_cast<std::size_t>(k)], work.positions, s, &out, &stage2_changed);
      }
      // Counting sort by stage-3 line (iy). It is stable, and the stage-2 lines ran in ascending ix,
      // each writing an output at most once: every line's positions come out sorted and distinct.
      std::fill(start.begin(), start.end(), 0);
      for (const Change& c : out) ++start[static_cast<std::size_t>(c.line - iz * ny + 1)];
      for (Index iy = 0; iy < ny; ++iy) start[static_cast<std::size_t>(iy + 1)] += start[static_cast<std::size_t>(iy)];
      slice.lines.clear();
      for (Index iy = 0; iy < ny; ++iy) {
        const Index b = start[static_cast<std::size_t>(iy)], e = start[static_cast<std::size_t>(iy + 1)];
        if (b < e) slice.lines.push_back({iz * ny + iy, b, b});
      }
      slice.positions.resize(out.size());
      for (const Change& c : out) {
        Index& cursor = start[static_cast<std::size_t>(c.line - iz * ny)];
        slice.positions[static_cast<std::size_t>(cursor++)] = {c.pos, c.low};
      }
      for (auto& l : slice.lines) l.end = start[static_cast<std::size_t>(l.line - iz * ny)];
      const Index n_lines = static_cast<Index>(slice.lines.size());
      for (Index k = 0; k < n_lines; ++k) {
        if (k + kPrefetchLines < n_lines)
          prefetch_line(3, slice.lines[static_cast<std::size_t>(k + kPrefetchLines)], slice.positions);
        update_line(3, slice.lines[static_cast<std::size_t>(k)], slice.positions, s, nullptr,
                    &changed[static_cast<std::size_t>(r)]);
      }
      lines_done[static_cast<std::size_t>(r)] = n_lines;
    }
  });
  *x_lines = 0;
  *n_changed = 0;
  for (Index r = 0; r < n_runs; ++r) {
    *x_lines += lines_done[static_cast<std::size_t>(r)];
    *n_changed += changed[static_cast<std::size_t>(r)];
  }
}

IncrementalEdtStats IncrementalEdt::update(const std::vector<Index>& index, const std::vector<std::uint8_t>& value,
                                           int nthreads) {
  const int nt = resolve_threads(nthreads);
  const Index nz = shape_[2];
  IncrementalEdtStats stats;
  Changes& changes = changes_;
  if (changes.empty()) changes.resize(1);

  // Apply the site changes; the columns holding a changed voxel are stage 1's work.
  for (std::size_t k = 0; k < index.size(); ++k) {
    const Index i = index[k];
    const std::uint8_t nv = value[k] ? 1 : 0;
    if (sites_[static_cast<std::size_t>(i)] != nv) {
      sites_[static_cast<std::size_t>(i)] = nv;
      changes[0].push_back({i / nz, static_cast<std::int32_t>(i % nz), 0});
    }
  }
  // A voxel toggled twice in one call is counted once per toggle; the stats are informative only.
  stats.changed_sites = static_cast<Index>(changes[0].size());
  const Work& columns = columns_;
  merge(changes, columns_);
  stats.columns = static_cast<Index>(columns.lines.size());

  const Index n_columns = stats.columns;
  {
    const Index chunk = chunk_size(n_columns, nt, 16);
    changes.resize(static_cast<std::size_t>((n_columns + chunk - 1) / chunk));
    parallel_chunks(n_columns, chunk, nt, [&](Index begin, Index end, Index c) {
      std::vector<double> buf(static_cast<std::size_t>(nz));
      auto& out = changes[static_cast<std::size_t>(c)];
      for (Index k = begin; k < end; ++k) column(columns.lines[static_cast<std::size_t>(k)].line, buf, &out);
    });
  }

  // Stage 2's work. Usually small: stages 2 and 3 then run slice by slice. When much of the grid
  // changed (e.g. the first scans), full passes are cheaper than the windows (each changed position
  // costs about a window of 2 * distance voxels), and stage 3 then has as much to do as stage 2.
  merge(changes, work_);
  stats.y_lines = static_cast<Index>(work_.lines.size());
  Index changed = 0;
  if (static_cast<Index>(work_.positions.size()) * kFullPassFactor > size()) {
    full_pass(2, nt);
    stats.x_lines = shape_[1] * shape_[2];
    changed = full_pass(3, nt);
  } else {
    update_slices(work_, nt, &stats.x_lines, &changed);
  }
  stats.changed_distances = changed;
  return stats;
}

}  // namespace cufund::esdf
