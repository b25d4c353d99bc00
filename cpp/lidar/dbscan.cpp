#include "dbscan.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>
#include <vector>

namespace cufund::lidar {

namespace {

// A cell's integer coordinates packed in one key (21 bits per axis, offset to stay positive).
inline std::uint64_t cell_key(std::int64_t i, std::int64_t j, std::int64_t k) {
  constexpr std::int64_t kOff = std::int64_t{1} << 20, kMask = (std::int64_t{1} << 21) - 1;
  return (static_cast<std::uint64_t>((i + kOff) & kMask) << 42) | (static_cast<std::uint64_t>((j + kOff) & kMask) << 21) |
         static_cast<std::uint64_t>((k + kOff) & kMask);
}

std::size_t find_root(std::vector<std::uint32_t>& parent, std::size_t i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

}  // namespace

std::int64_t dbscan(const double* points, std::size_t n, double eps, std::size_t min_points, std::int64_t* labels) {
  if (n == 0) return 0;
  // Cells a hair wider than eps from the cloud's lower corner: a neighbour is in one of the 27 around.
  const double cell_edge = eps * (1.0 + 1e-9);
  double lo[3] = {points[0], points[1], points[2]};
  for (std::size_t i = 1; i < n; ++i) {
    for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], points[3 * i + c]);
  }
  std::vector<std::int64_t> cell(3 * n);
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int c = 0; c < 3; ++c) cell[3 * i + c] = static_cast<std::int64_t>(std::floor((points[3 * i + c] - lo[c]) / cell_edge));
    keyed[i] = {cell_key(cell[3 * i], cell[3 * i + 1], cell[3 * i + 2]), static_cast<std::uint32_t>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  // Neighbour lists, each point's own included, as the radius search reports them; cell by cell, so
  // that the 27 cells around are looked up once per cell.
  const double eps2 = eps * eps;
  std::vector<std::vector<std::uint32_t>> near(n);
  std::pair<std::size_t, std::size_t> ranges[27];
  for (std::size_t c0 = 0; c0 < n;) {
    std::size_t c1 = c0;
    while (c1 < n && keyed[c1].first == keyed[c0].first) ++c1;
    const std::int64_t* ijk = cell.data() + 3 * std::size_t{keyed[c0].second};
    int r = 0;
    for (int di = -1; di <= 1; ++di) {
      for (int dj = -1; dj <= 1; ++dj) {
        for (int dk = -1; dk <= 1; ++dk) {
          const std::uint64_t key = cell_key(ijk[0] + di, ijk[1] + dj, ijk[2] + dk);
          auto lo_it = std::lower_bound(keyed.begin(), keyed.end(), std::make_pair(key, std::uint32_t{0}));
          auto hi_it = lo_it;
          while (hi_it != keyed.end() && hi_it->first == key) ++hi_it;
          ranges[r++] = {static_cast<std::size_t>(lo_it - keyed.begin()), static_cast<std::size_t>(hi_it - keyed.begin())};
        }
      }
    }
    for (std::size_t a = c0; a < c1; ++a) {
      const std::uint32_t i = keyed[a].second;
      const double* p = points + 3 * std::size_t{i};
      auto& row = near[i];
      for (const auto& [lo_k, hi_k] : ranges) {
        for (std::size_t b = lo_k; b < hi_k; ++b) {
          const double* q = points + 3 * std::size_t{keyed[b].second};
          const double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
          if (dx * dx + dy * dy + dz * dz < eps2) row.push_back(keyed[b].second);
        }
      }
    }
    c0 = c1;
  }
  std::vector<std::uint32_t> start(n + 1, 0), nbr;
  for (std::size_t i = 0; i < n; ++i) start[i + 1] = start[i] + static_cast<std::uint32_t>(near[i].size());
  nbr.reserve(start[n]);
  for (auto& row : near) {
    nbr.insert(nbr.end(), row.begin(), row.end());
    std::vector<std::uint32_t>().swap(row);
  }
  std::vector<char> core(n);
  for (std::size_t i = 0; i < n; ++i) core[i] = (start[i + 1] - start[i]) >= min_points;
  // Union-find over core-core links; the root of a group is its lowest index.
  std::vector<std::uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0u);
  for (std::size_t i = 0; i < n; ++i) {
    if (!core[i]) continue;
    for (std::uint32_t e = start[i]; e < start[i + 1]; ++e) {
      const std::uint32_t j = nbr[e];
      if (j <= i || !core[j]) continue;
      std::size_t a = find_root(parent, i), b = find_root(parent, j);
      if (a == b) continue;
      if (a > b) std::swap(a, b);
      parent[b] = static_cast<std::uint32_t>(a);
    }
  }
  std::vector<std::int64_t> cluster_of_root(n, -1);
  std::int64_t clusters = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (core[i] && find_root(parent, i) == i) cluster_of_root[i] = clusters++;
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (core[i]) {
      labels[i] = cluster_of_root[find_root(parent, i)];
      continue;
    }
    std::int64_t best = -1;
    for (std::uint32_t e = start[i]; e < start[i + 1]; ++e) {
      const std::uint32_t j = nbr[e];
      if (!core[j]) continue;
      const std::int64_t c = cluster_of_root[find_root(parent, j)];
      if (best < 0 || c < best) best = c;
    }
    labels[i] = best;
  }
  return clusters;
}

}  // namespace cufund::lidar
