#include "incremental_edt.h"

#include <algorithm>
#include <cmath>

#include "edt.h"
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

}  // namespace

struct IncrementalEdt::Scratch : LineBuffers {
  explicit Scratch(Index n) : LineBuffers(kGroup, n) {}
  std::vector<std::pair<Index, Index>> windows;
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
      if (changed) changed->push_back({q * nx + ix, iy, std::min(old, nv)});  // stage-2 line (iz = q, ix)
      old = nv;
    }
  }
}

void IncrementalEdt::full_pass(int stage, int nthreads, Changes* changed, Index* n_changed) {
  const Index nx = shape_[0], ny = shape_[1], nz = shape_[2];
  const Index lines = stage == 2 ? nx * nz : ny * nz;
  const Index group = stage == 2 ? kGroup : 1;
  const Index groups = (lines + group - 1) / group;
  const Index n = stage == 2 ? ny : nx;
  const Index chunk = chunk_size(groups, nthreads, 4);
  const Index chunks = (groups + chunk - 1) / chunk;
  std::vector<Index> totals(static_cast<std::size_t>(chunks), 0);
  if (changed && static_cast<Index>(changed->size()) < chunks) changed->resize(static_cast<std::size_t>(chunks));
  parallel_chunks(groups, chunk, nthreads, [&](Index g_begin, Index g_end, Index c) {
    Scratch s(n);
    auto* out = changed ? &(*changed)[static_cast<std::size_t>(c)] : nullptr;
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
          if (o != nv) {
            ++total;
            if (out) {  // stage-3 line (iz, iy = q), position ix
              const Index line = first + j;
              out->push_back({(line / nx) * ny + q, line % nx, std::min(o, nv)});
            }
            o = nv;
          }
        }
      }
    }
  });
  Index total = 0;
  for (Index t : totals) total += t;
  if (n_changed) *n_changed = total;
}

void IncrementalEdt::update_line(int stage, const LineWork& work, const std::vector<Position>& positions, Scratch& s,
                                 std::vector<Change>* changed, Index* n_changed) {
  const Index nx = shape_[0], ny = shape_[1];
  const LineView v = view(stage, work.line);
  const Index n = v.n;
  const auto old = [&](Index q) { return v.out[q * v.out_stride]; };
  // Output windows. q can change only if low(p) + (q - p)^2 <= old(q) for a changed p (else the old
  // minimum came from an unchanged input and no changed input gets below it). For one p these q form
  // an interval (where a parabola lies under a lower envelope of parabolas), inside the q with
  // (q - p)^2 <= old(q), which are contiguous around p because D = sqrt(old) is 1-Lipschitz along a
  // line. Walking away from p, the same Lipschitz bound skips q that provably fail.
  auto& windows = s.windows;
  windows.clear();
  for (Index k = work.begin; k < work.end; ++k) {
    const Index p = positions[static_cast<std::size_t>(k)].pos;
    const Index low = positions[static_cast<std::size_t>(k)].low;
    Index a = n, b = -1;
    bool p_in = false;
    for (const Index dir : {Index{1}, Index{-1}}) {
      if (dir < 0 && b >= a && !p_in) break;  // the interval lies right of p
      bool found = false;
      for (Index q = dir > 0 ? p : p - 1; q >= 0 && q < n;) {
        const std::int32_t g = old(q);
        const Index d = dir > 0 ? q - p : p - q;
        if (g == kNoSite || low + d * d <= static_cast<Index>(g)) {
          a = std::min(a, q);
          b = std::max(b, q);
          found = true;
          if (q == p) p_in = true;
          q += dir;
          continue;
        }
        if (found || d * d > static_cast<Index>(g)) break;  // left the interval, or past the bound
        // Here low + d^2 > old(q) = D^2 with d <= D. At d + j, old <= (D + j)^2, so the gap stays
        // positive while j < gap / (2 (D - d)).
        const double D = std::sqrt(static_cast<double>(g));
        if (D <= static_cast<double>(d)) break;
        const double gap = static_cast<double>(low + d * d - static_cast<Index>(g));
        const Index skip = static_cast<Index>(std::floor(gap / (2.0 * (D - static_cast<double>(d))) - 1e-9));
        q += dir * (std::max<Index>(skip, 0) + 1);
      }
    }
    if (a <= b) windows.emplace_back(a, b);
  }
  std::sort(windows.begin(), windows.end());
  std::size_t w = 0;
  while (w < windows.size()) {
    Index lo = windows[w].first, hi = windows[w].second;
    for (++w; w < windows.size() && windows[w].first <= hi + 1; ++w) hi = std::max(hi, windows[w].second);
    // Input window: every site that can be nearest to some q in [lo, hi]. Start from the old
    // distances (enough where distances only shrink: the nearest site is then within sqrt(old(q)))
    // and widen until provably enough: a site outside [wlo, whi] is at least (q - wlo + 1) or
    // (whi + 1 - q) away from q.
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
      bool exact = true;
      for (Index q = lo; q <= hi && exact; ++q) {
        const double r = s.d[static_cast<std::size_t>(q - wlo)];
        const double left = static_cast<double>(q - wlo + 1), right = static_cast<double>(whi + 1 - q);
        exact = !((wlo > 0 && r > left * left) || (whi < n - 1 && r > right * right));
      }
      if (!exact) {  // some distance grew: widen both sides by the window's length
        wlo = std::max(Index{0}, wlo - m);
        whi = std::min(n - 1, whi + m);
        continue;
      }
      for (Index q = lo; q <= hi; ++q) {
        const std::int32_t nv = to_int(s.d[static_cast<std::size_t>(q - wlo)]);
        std::int32_t& o = v.out[q * v.out_stride];
        if (o != nv) {
          ++*n_changed;
          if (changed) {  // stage-3 line (iz, iy = q), position ix
            const Index iz = work.line / nx, ix = work.line % nx;
            changed->push_back({iz * ny + q, ix, std::min(o, nv)});
          }
          o = nv;
        }
      }
      break;
    }
  }
}

IncrementalEdt::Work IncrementalEdt::merge(Changes& changes) {
  Work w;
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
    std::sort(b, e, [](const Position& x, const Position& y) { return x.pos < y.pos || (x.pos == y.pos && x.low < y.low); });
    l.end = l.begin + (std::unique(b, e, [](const Position& x, const Position& y) { return x.pos == y.pos; }) - b);
  }
  return w;
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
  full_pass(2, nt, nullptr, nullptr);
  full_pass(3, nt, nullptr, nullptr);
}

IncrementalEdtStats IncrementalEdt::update(const std::vector<Index>& index, const std::vector<std::uint8_t>& value,
                                           int nthreads) {
  const int nt = resolve_threads(nthreads);
  const Index nz = shape_[2];
  const Index longest = std::max({shape_[0], shape_[1], shape_[2]});
  IncrementalEdtStats stats;
  Changes changes(1);

  // Apply the site changes; the columns holding a changed voxel are stage 1's work.
  for (std::size_t k = 0; k < index.size(); ++k) {
    const Index i = index[k];
    const std::uint8_t nv = value[k] ? 1 : 0;
    if (sites_[static_cast<std::size_t>(i)] != nv) {
      sites_[static_cast<std::size_t>(i)] = nv;
      changes[0].push_back({i / nz, i % nz, 0});
    }
  }
  // A voxel toggled twice in one call is counted once per toggle; the stats are informative only.
  stats.changed_sites = static_cast<Index>(changes[0].size());
  const Work columns = merge(changes);
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

  Index changed = 0;
  for (int stage = 2; stage <= 3; ++stage) {
    const Work work = merge(changes);
    (stage == 2 ? stats.y_lines : stats.x_lines) = static_cast<Index>(work.lines.size());
    const Index n_lines = static_cast<Index>(work.lines.size());
    Index stage_changed = 0;
    // When much of the grid changed (e.g. the first scans), one full pass is cheaper than the windows
    // (each changed position costs about a window of 2 * distance voxels).
    if (static_cast<Index>(work.positions.size()) * kFullPassFactor > size()) {
      full_pass(stage, nt, stage == 2 ? &changes : nullptr, &stage_changed);
      if (stage == 3) changed = stage_changed;
      continue;
    }
    const Index chunk = chunk_size(n_lines, nt, 8);
    const Index chunks = (n_lines + chunk - 1) / chunk;
    if (stage == 2) changes.resize(std::max(changes.size(), static_cast<std::size_t>(chunks)));
    std::vector<Index> counts(static_cast<std::size_t>(chunks), 0);
    parallel_chunks(n_lines, chunk, nt, [&](Index begin, Index end, Index c) {
      Scratch s(longest);
      auto* out = stage == 2 ? &changes[static_cast<std::size_t>(c)] : nullptr;
      for (Index k = begin; k < end; ++k) {
        update_line(stage, work.lines[static_cast<std::size_t>(k)], work.positions, s, out,
                    &counts[static_cast<std::size_t>(c)]);
      }
    });
    for (Index c : counts) stage_changed += c;
    if (stage == 3) changed = stage_changed;
  }
  stats.changed_distances = changed;
  return stats;
}

}  // namespace cufund::esdf
