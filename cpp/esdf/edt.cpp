#include "edt.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "edt_line.h"
#include "parallel.h"

namespace cufund::esdf {
namespace {

using Index = std::ptrdiff_t;

// Lines along a strided axis are processed this many at a time, so each cache line fetched by the
// gather serves several lines.
constexpr Index kBlock = 16;

// Per-thread buffers for kBlock lines of length n.
struct LineScratch : LineBuffers {
  explicit LineScratch(Index n) : LineBuffers(kBlock, n) {}
};

// Pass along the contiguous last axis: squared distance to the nearest site (or non-site if
// `invert`) along each line.
template <typename T>
void pass_contiguous(const std::uint8_t* sites, bool invert, Index lines, Index n, double spacing, bool take_sqrt,
                     int nthreads, T* out) {
  parallel_chunks(lines, chunk_size(lines, nthreads, 64), nthreads, [&](Index begin, Index end, Index) {
    std::vector<std::uint8_t> inv(invert ? static_cast<std::size_t>(n) : 0);
    std::vector<double> d(static_cast<std::size_t>(n));
    for (Index l = begin; l < end; ++l) {
      const std::uint8_t* s = sites + l * n;
      if (invert) {
        for (Index q = 0; q < n; ++q) inv[static_cast<std::size_t>(q)] = s[q] ? 0 : 1;
        s = inv.data();
      }
      squared_distance_to_sites_1d(s, 1, n, spacing, d.data());
      T* o = out + l * n;
      if (take_sqrt) {
        for (Index q = 0; q < n; ++q) o[q] = static_cast<T>(std::sqrt(d[static_cast<std::size_t>(q)]));
      } else {
        for (Index q = 0; q < n; ++q) o[q] = static_cast<T>(d[static_cast<std::size_t>(q)]);
      }
    }
  });
}

// Lower-envelope pass along an axis of length n and stride `stride` (in elements), for a grid seen
// as [outer][n][inner] with inner == stride.
template <typename T>
void pass_strided(Index outer, Index n, Index inner, double spacing, bool take_sqrt, int nthreads, T* grid) {
  const Index blocks_per_outer = (inner + kBlock - 1) / kBlock;
  const Index tasks = outer * blocks_per_outer;
  parallel_chunks(tasks, chunk_size(tasks, nthreads, 1), nthreads, [&](Index begin, Index end, Index) {
    LineScratch s(n);
    for (Index t = begin; t < end; ++t) {
      const Index o = t / blocks_per_outer;
      const Index i0 = (t % blocks_per_outer) * kBlock;
      const Index b = std::min(kBlock, inner - i0);
      T* base = grid + o * n * inner + i0;
      for (Index q = 0; q < n; ++q) {
        const T* row = base + q * inner;
        for (Index j = 0; j < b; ++j) s.f[static_cast<std::size_t>(j * n + q)] = static_cast<double>(row[j]);
      }
      for (Index j = 0; j < b; ++j) {
        lower_envelope_1d(s.f.data() + j * n, s.d.data() + j * n, n, spacing, s.v.data(), s.z.data());
      }
      for (Index q = 0; q < n; ++q) {
        T* row = base + q * inner;
        if (take_sqrt) {
          for (Index j = 0; j < b; ++j) row[j] = static_cast<T>(std::sqrt(s.d[static_cast<std::size_t>(j * n + q)]));
        } else {
          for (Index j = 0; j < b; ++j) row[j] = static_cast<T>(s.d[static_cast<std::size_t>(j * n + q)]);
        }
      }
    }
  });
}

template <typename T>
void unsigned_transform(const std::uint8_t* sites, bool invert, const std::array<Index, 3>& n,
                        const std::array<double, 3>& h, int nthreads, T* out) {
  const bool do1 = n[1] > 1, do0 = n[0] > 1;
  pass_contiguous(sites, invert, n[0] * n[1], n[2], h[2], !do1 && !do0, nthreads, out);
  if (do1) pass_strided(n[0], n[1], n[2], h[1], !do0, nthreads, out);
  if (do0) pass_strided(Index{1}, n[0], n[1] * n[2], h[0], true, nthreads, out);
}

}  // namespace

template <typename T>
EdtStatus euclidean_distance_transform(const std::uint8_t* sites, const std::array<std::ptrdiff_t, 3>& shape,
                                       const EdtOptions& options, T* out) {
  for (Index s : shape) {
    if (s < 1) return EdtStatus::kBadShape;
  }
  for (double h : options.voxel_size) {
    if (!std::isfinite(h) || h <= 0.0) return EdtStatus::kBadVoxelSize;
  }
  const int nt = resolve_threads(options.nthreads);
  unsigned_transform(sites, false, shape, options.voxel_size, nt, out);
  if (options.signed_distance) {
    const Index total = shape[0] * shape[1] * shape[2];
    std::vector<T> inside(static_cast<std::size_t>(total));
    unsigned_transform(sites, true, shape, options.voxel_size, nt, inside.data());
    parallel_chunks(total, chunk_size(total, nt, 4096), nt, [&](Index begin, Index end, Index) {
      for (Index i = begin; i < end; ++i) out[i] -= inside[static_cast<std::size_t>(i)];
    });
  }
  return EdtStatus::kOk;
}

template EdtStatus euclidean_distance_transform<float>(const std::uint8_t*, const std::array<std::ptrdiff_t, 3>&,
                                                       const EdtOptions&, float*);
template EdtStatus euclidean_distance_transform<double>(const std::uint8_t*, const std::array<std::ptrdiff_t, 3>&,
                                                        const EdtOptions&, double*);

}  // namespace cufund::esdf
