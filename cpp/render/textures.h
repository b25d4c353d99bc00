// Procedural surface textures of the camera renderer: a scalar pattern f in [0, 1] at plane coordinates (a, b)
// in units of the material's scale. Noise-based textures read a periodic square tile of value noise (made once per
// seed by cufund.worlds.materials); checker and brick are analytic.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace cufund::render {

enum class Texture : std::int32_t {
  kNone = 0,
  kChecker = 1,
  kNoise = 2,
  kBrick = 3,
  kBark = 4,
  kConcrete = 5,
  kExternal = 6,  // coloured by the caller (image textures through UVs): the renderer writes the plain albedo
};

inline constexpr int kNoiseCells = 32;  // base noise cells across a tile

// Bilinear lookup of a periodic n x n tile (row-major, rows along b) at (a, b) in tile periods.
inline float tile_lookup(const float* tile, int n, double a, double b) {
  const double x = (a - std::floor(a)) * n, y = (b - std::floor(b)) * n;
  const double fx = std::floor(x), fy = std::floor(y);
  // x, y in [0, n]: only x == n (a rounding of a just below 1) wraps
  const int i0 = static_cast<int>(fx) == n ? 0 : static_cast<int>(fx),
            j0 = static_cast<int>(fy) == n ? 0 : static_cast<int>(fy);
  const int i1 = i0 + 1 == n ? 0 : i0 + 1, j1 = j0 + 1 == n ? 0 : j0 + 1;
  const float tx = static_cast<float>(x - fx), ty = static_cast<float>(y - fy);
  const float top = tile[j0 * n + i0] * (1 - tx) + tile[j0 * n + i1] * tx;
  const float bot = tile[j1 * n + i0] * (1 - tx) + tile[j1 * n + i1] * tx;
  return top * (1 - ty) + bot * ty;
}

// Deterministic value in [0, 1) per integer lattice cell (i, j).
inline float cell_hash(std::int64_t i, std::int64_t j, std::uint32_t seed) {
  std::uint64_t h = static_cast<std::uint64_t>(i) * 73856093ull ^ static_cast<std::uint64_t>(j) * 19349663ull ^
                    (static_cast<std::uint64_t>(seed) * 83492791ull + 1ull);
  h = (h ^ (h >> 13)) * 1274126177ull;
  h ^= h >> 16;
  return static_cast<float>(h & 0xFFFFu) / 65536.0f;
}

// Where a seed reads the shared noise tile: (da, db) [scale units] added to a noise-based texture's coordinates.
inline void seed_shift(std::uint32_t seed, double& da, double& db) {
  da = kNoiseCells * cell_hash(seed, 1, 0x9E3779B9u);
  db = kNoiseCells * cell_hash(seed, 2, 0x85EBCA6Bu);
}

// The pattern at (a, b) already shifted by seed_shift (the renderer shifts once per material).
inline float pattern_shifted(Texture texture, double a, double b, const float* tile, int n, std::uint32_t seed) {
  constexpr double c = kNoiseCells;
  switch (texture) {
    case Texture::kChecker: {
      const auto s = static_cast<std::int64_t>(std::floor(a)) + static_cast<std::int64_t>(std::floor(b));
      return (s & 1) == 0 ? 1.0f : 0.0f;
    }
    case Texture::kNoise: return tile_lookup(tile, n, a / c, b / c);
    case Texture::kConcrete: {
      const float fine = tile_lookup(tile, n, a / (c / 4), b / (c / 4));
      const float blotch = tile_lookup(tile, n, a / (2 * c) + 0.37, b / (2 * c) + 0.61);
      return std::clamp(0.55f + 0.7f * (fine - 0.5f) + 0.5f * (blotch - 0.5f), 0.0f, 1.0f);
    }
    case Texture::kBark:  // vertical ridges: noise stretched 8x along b
      return std::clamp(0.5f + 1.4f * (tile_lookup(tile, n, a / (c / 4), b / (2 * c)) - 0.5f), 0.0f, 1.0f);
    case Texture::kBrick: {  // running bond, bricks 1 x 1/3 (scale units), mortar 3% of the length, 8% of the height
      constexpr double h = 1.0 / 3.0;
      const double row = std::floor(b / h);
      const double x = a + 0.5 * std::fmod(std::fabs(row), 2.0);
      const double col = std::floor(x);
      if (x - col < 0.03 || b / h - row < 0.08) return 0.0f;
      const float shade = cell_hash(static_cast<std::int64_t>(row), static_cast<std::int64_t>(col), seed);
      const float grain = tile_lookup(tile, n, a / (c / 8), b / (c / 8));
      return std::clamp(0.55f + 0.3f * shade + 0.3f * (grain - 0.5f), 0.0f, 1.0f);
    }
    case Texture::kNone:
    case Texture::kExternal: break;
  }
  return 1.0f;
}

// The pattern of `texture` at (a, b) [scale units]; `tile` (n x n) may be null for checker and none. Noise-based
// textures of different seeds read the same tile at seed-dependent offsets (seed_shift).
float pattern(Texture texture, double a, double b, const float* tile, int n, std::uint32_t seed);

}  // namespace cufund::render
