#include "incremental_edt.h"

#include <omp.h>

#include <algorithm>

#include "edt.h"
#include "edt_line.h"

namespace cufund::esdf {
namespace {

using Index = IncrementalEdt::Index;

inline double to_double(std::int32_t v) { return v == IncrementalEdt::kNoSite ? kInf : static_cast<double>(v); }
// Lower envelopes of integer data are integers, exact in double for any grid that fits in memory.
inline std::int32_t to_int(double v) { return v == kInf ? IncrementalEdt::kNoSite : static_cast<std::int32_t>(v); }

// Per-thread line buffers.
struct Scratch {
  explicit Scratch(Index n)
      : f(static_cast<std::size_t>(n)), d(static_cast<std::size_t>(n)), v(static_cast<std::size_t>(n)),
        z(static_cast<std::size_t>(n + 1)) {}
  std::vector<double> f, d;
  std::vector<Index> v;
  std::vector<double> z;
};

// Merges per-thread lists into one sorted list without duplicates, using `flag` (all zero on entry
// and on return) to deduplicate.
std::vector<Index> merge_unique(std::vector<std::vector<Index>>& lists, std::vector<std::uint8_t>& flag) {
  std::vector<Index> merged;
  for (auto& list : lists) {
    for (Index i : list) {
      auto& f = flag[static_cast<std::size_t>(i)];
      if (!f) {
        f = 1;
        merged.push_back(i);
      }
    }
    list.clear();
  }
  for (Index i : merged) flag[static_cast<std::size_t>(i)] = 0;
  std::sort(merged.begin(), merged.end());
  return merged;
}

}  // namespace

IncrementalEdt::IncrementalEdt(const std::array<Index, 3>& shape)
    : shape_(shape),
      sites_(static_cast<std::size_t>(size()), 0),
      g1_(static_cast<std::size_t>(size()), kNoSite),
      g2_(static_cast<std::size_t>(size()), kNoSite),
      g3_(static_cast<std::size_t>(size()), kNoSite),
      column_flag_(static_cast<std::size_t>(shape[0] * shape[1]), 0),
      y_flag_(static_cast<std::size_t>(shape[0] * shape[2]), 0),
      x_flag_(static_cast<std::size_t>(shape[1] * shape[2]), 0) {}

// Stage 1: column c = (ix, iy), squared distance to the nearest site along z.
void IncrementalEdt::column(Index c, std::vector<double>& buf, std::vector<Index>* changed) {
  const Index nz = shape_[2];
  const Index base = c * nz;
  squared_distance_to_sites_1d(sites_.data() + base, 1, nz, 1.0, buf.data());
  for (Index q = 0; q < nz; ++q) {
    const std::int32_t nv = to_int(buf[static_cast<std::size_t>(q)]);
    std::int32_t& old = g1_[static_cast<std::size_t>(base + q)];
    if (nv != old) {
      old = nv;
      if (changed) changed->push_back((c / shape_[1]) * nz + q);  // y-line (ix, iz)
    }
  }
}

// Stage 2: y-line l = (ix, iz), lower envelope of stage 1 along y.
void IncrementalEdt::y_line(Index l, std::vector<double>& f, std::vector<double>& d, std::vector<Index>& v,
                            std::vector<double>& z, std::vector<Index>* changed) {
  const Index ny = shape_[1], nz = shape_[2];
  const Index ix = l / nz, iz = l % nz;
  const Index base = ix * ny * nz + iz;
  for (Index q = 0; q < ny; ++q) f[static_cast<std::size_t>(q)] = to_double(g1_[static_cast<std::size_t>(base + q * nz)]);
  lower_envelope_1d(f.data(), d.data(), ny, 1.0, v.data(), z.data());
  for (Index q = 0; q < ny; ++q) {
    const std::int32_t nv = to_int(d[static_cast<std::size_t>(q)]);
    std::int32_t& old = g2_[static_cast<std::size_t>(base + q * nz)];
    if (nv != old) {
      old = nv;
      if (changed) changed->push_back(q * nz + iz);  // x-line (iy, iz)
    }
  }
}

// Stage 3: x-line l = (iy, iz), lower envelope of stage 2 along x.
void IncrementalEdt::x_line(Index l, std::vector<double>& f, std::vector<double>& d, std::vector<Index>& v,
                            std::vector<double>& z, Index* changed) {
  const Index nx = shape_[0], stride = shape_[1] * shape_[2];
  for (Index q = 0; q < nx; ++q) f[static_cast<std::size_t>(q)] = to_double(g2_[static_cast<std::size_t>(l + q * stride)]);
  lower_envelope_1d(f.data(), d.data(), nx, 1.0, v.data(), z.data());
  for (Index q = 0; q < nx; ++q) {
    const std::int32_t nv = to_int(d[static_cast<std::size_t>(q)]);
    std::int32_t& old = g3_[static_cast<std::size_t>(l + q * stride)];
    if (nv != old) {
      old = nv;
      ++*changed;
    }
  }
}

void IncrementalEdt::reset(const std::uint8_t* sites, int nthreads) {
  for (Index i = 0; i < size(); ++i) sites_[static_cast<std::size_t>(i)] = sites[i] ? 1 : 0;
  recompute(nthreads);
}

void IncrementalEdt::recompute(int nthreads) {
  const int nt = resolve_threads(nthreads);
  const Index nx = shape_[0], ny = shape_[1], nz = shape_[2];
  const Index longest = std::max({nx, ny, nz});
#pragma omp parallel num_threads(nt)
  {
    Scratch s(longest);
    Index unused = 0;
#pragma omp for schedule(static)
    for (Index c = 0; c < nx * ny; ++c) column(c, s.f, nullptr);
#pragma omp for schedule(static)
    for (Index l = 0; l < nx * nz; ++l) y_line(l, s.f, s.d, s.v, s.z, nullptr);
#pragma omp for schedule(static)
    for (Index l = 0; l < ny * nz; ++l) x_line(l, s.f, s.d, s.v, s.z, &unused);
  }
}

IncrementalEdtStats IncrementalEdt::update(const std::vector<Index>& index, const std::vector<std::uint8_t>& value,
                                           int nthreads) {
  const int nt = resolve_threads(nthreads);
  const Index nx = shape_[0], ny = shape_[1], nz = shape_[2];
  const Index longest = std::max({nx, ny, nz});
  IncrementalEdtStats stats;
  std::vector<std::vector<Index>> lists(static_cast<std::size_t>(nt));

  // Apply the site changes; the columns holding a changed voxel are stage 1's work.
  for (std::size_t k = 0; k < index.size(); ++k) {
    const Index i = index[k];
    const std::uint8_t nv = value[k] ? 1 : 0;
    if (sites_[static_cast<std::size_t>(i)] != nv) {
      sites_[static_cast<std::size_t>(i)] = nv;
      lists[0].push_back(i / nz);
    }
  }
  // A voxel toggled twice in one call is counted once per toggle; the stats are informative only.
  stats.changed_sites = static_cast<Index>(lists[0].size());
  const std::vector<Index> columns = merge_unique(lists, column_flag_);
  stats.columns = static_cast<Index>(columns.size());

  const Index n_columns = static_cast<Index>(columns.size());
#pragma omp parallel num_threads(nt)
  {
    std::vector<double> buf(static_cast<std::size_t>(nz));
    auto& out = lists[static_cast<std::size_t>(omp_get_thread_num())];
#pragma omp for schedule(dynamic, 16)
    for (Index k = 0; k < n_columns; ++k) column(columns[static_cast<std::size_t>(k)], buf, &out);
  }
  const std::vector<Index> y_lines = merge_unique(lists, y_flag_);
  stats.y_lines = static_cast<Index>(y_lines.size());

  const Index n_y = static_cast<Index>(y_lines.size());
#pragma omp parallel num_threads(nt)
  {
    Scratch s(longest);
    auto& out = lists[static_cast<std::size_t>(omp_get_thread_num())];
#pragma omp for schedule(dynamic, 16)
    for (Index k = 0; k < n_y; ++k) y_line(y_lines[static_cast<std::size_t>(k)], s.f, s.d, s.v, s.z, &out);
  }
  const std::vector<Index> x_lines = merge_unique(lists, x_flag_);
  stats.x_lines = static_cast<Index>(x_lines.size());

  const Index n_x = static_cast<Index>(x_lines.size());
  Index changed = 0;
#pragma omp parallel num_threads(nt) reduction(+ : changed)
  {
    Scratch s(longest);
#pragma omp for schedule(dynamic, 16)
    for (Index k = 0; k < n_x; ++k) x_line(x_lines[static_cast<std::size_t>(k)], s.f, s.d, s.v, s.z, &changed);
  }
  stats.changed_distances = changed;
  return stats;
}

}  // namespace cufund::esdf
