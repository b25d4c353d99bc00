#include "dbscan.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>
#include <vector>

namespace cufund::perception {

namespace {

// A cell's integer coordinates packed in one key (21 bits per axis, offset to stay positive).
inline std::uint64_t cell_key(std::int64_t i, std::int64_t j, std::int64_t k) {
  constexpr std::int64_t kOff = std::int64_t{1} << 20, kMask = (std::int64_t{1} << 21) - 1;
  return (static_cast<std::uint64_t>((i + kOff) & kMask) << 42) |
         (static_cast<std::uint64_t>((j + kOff) & kMask) << 21) | static_cast<std::uint64_t>((k + kOff) & kMask);
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
    for (int c = 0; c < 3; ++c)
      cell[3 * i + c] = static_cast<std::int64_t>(std::floor((points[3 * i + c] - lo[c]) / cell_edge));
    keyed[i] = {cell_key(cell[3 * i], cell[3 * i + 1], cell[3 * i + 2]), static_cast<std::uint32_t>(i)};
  }
  std::sort(keyed.begin(), keyed.end());
  // Every pair closer than eps, once: within a cell, and with the 13 cells after it in key order.
  const double eps2 = eps * eps;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  pairs.reserve(16 * n);
  std::vector<std::uint32_t> degree(n, 1);  // the point itself counts, as in a radius search
  auto close = [&](std::uint32_t i, std::uint32_t j) {
    const double* p = points + 3 * std::size_t{i};
    const double* q = points + 3 * std::size_t{j};
    const double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
    if (dx * dx + dy * dy + dz * dz < eps2) {
      pairs.emplace_back(i, j);
      ++degree[i];
      ++degree[j];
    }
  };
  for (std::size_t c0 = 0; c0 < n;) {
    std::size_t c1 = c0;
    while (c1 < n && keyed[c1].first == keyed[c0].first) ++c1;
    for (std::size_t a = c0; a < c1; ++a) {
      for (std::size_t b = a + 1; b < c1; ++b) close(keyed[a].second, keyed[b].second);
    }
    const std::int64_t* ijk = cell.data() + 3 * std::size_t{keyed[c0].second};
    for (int di = 0; di <= 1; ++di) {
      for (int dj = -1; dj <= 1; ++dj) {
        for (int dk = -1; dk <= 1; ++dk) {
          if (di == 0 && (dj < 0 || (dj == 0 && dk <= 0))) continue;  // the 13 cells after this one
          const std::uint64_t key = cell_key(ijk[0] + di, ijk[1] + dj, ijk[2] + dk);
          auto it = std::lower_bound(keyed.begin() + static_cast<std::ptrdiff_t>(c1), keyed.end(),
                                     std::make_pair(key, std::uint32_t{0}));
          std::size_t e = static_cast<std::size_t>(it - keyed.begin());
          std::size_t f = e;
          while (f < n && keyed[f].first == key) ++f;
          if (e == f) continue;
          for (std::size_t a = c0; a < c1; ++a) {
            for (std::size_t b = e; b < f; ++b) close(keyed[a].second, keyed[b].second);
          }
        }
      }
    }
    c0 = c1;
  }
  std::vector<char> core(n);
  for (std::size_t i = 0; i < n; ++i) core[i] = degree[i] >= min_points;
  // Union-find over core-core links; the root of a group is its lowest index.
  std::vector<std::uint32_t> parent(n);
  std::iota(parent.begin(), parent.end(), 0u);
  for (const auto& [i, j] : pairs) {
    if (!core[i] || !core[j]) continue;
    std::size_t a = find_root(parent, i), b = find_root(parent, j);
    if (a == b) continue;
    if (a > b) std::swap(a, b);
    parent[b] = static_cast<std::uint32_t>(a);
  }
  std::vector<std::int64_t> cluster_of_root(n, -1);
  std::int64_t clusters = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (core[i] && find_root(parent, i) == i) cluster_of_root[i] = clusters++;
  }
  for (std::size_t i = 0; i < n; ++i) labels[i] = core[i] ? cluster_of_root[find_root(parent, i)] : -1;
  // A border point joins the lowest-numbered cluster among its core neighbours.
  for (const auto& [i, j] : pairs) {
    if (core[i] == core[j]) continue;
    const std::uint32_t border = core[i] ? j : i;
    const std::int64_t c = labels[core[i] ? i : j];
    if (labels[border] < 0 || c < labels[border]) labels[border] = c;
  }
  return clusters;
}

}  // namespace cufund::perception
