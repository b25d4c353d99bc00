// Brute-force references for the esdf tests: O(voxels x sites), obviously correct.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

namespace cufund::esdf::test {

using Index = std::ptrdiff_t;

// Squared distance from every voxel centre to the nearest site centre, per-axis spacing h.
inline std::vector<double> brute_squared(const std::vector<std::uint8_t>& sites, const std::array<Index, 3>& n,
                                         const std::array<double, 3>& h) {
  std::vector<double> out(sites.size(), std::numeric_limits<double>::infinity());
  for (Index i = 0; i < n[0]; ++i)
    for (Index j = 0; j < n[1]; ++j)
      for (Index k = 0; k < n[2]; ++k) {
        double best = std::numeric_limits<double>::infinity();
        for (Index a = 0; a < n[0]; ++a)
          for (Index b = 0; b < n[1]; ++b)
            for (Index c = 0; c < n[2]; ++c) {
              if (!sites[static_cast<std::size_t>((a * n[1] + b) * n[2] + c)]) continue;
              const double dx = h[0] * static_cast<double>(a - i), dy = h[1] * static_cast<double>(b - j),
                           dz = h[2] * static_cast<double>(c - k);
              best = std::min(best, dx * dx + dy * dy + dz * dz);
            }
        out[static_cast<std::size_t>((i * n[1] + j) * n[2] + k)] = best;
      }
  return out;
}

inline std::vector<std::uint8_t> random_sites(Index size, double density, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::bernoulli_distribution coin(density);
  std::vector<std::uint8_t> s(static_cast<std::size_t>(size));
  for (auto& v : s) v = coin(rng) ? 1 : 0;
  return s;
}

}  // namespace cufund::esdf::test
