// Procedural surface textures of the camera renderer: a scalar pattern f in [0, 1] at plane coordinates (a, b)
// in units of the material's scale. Noise-based textures read a periodic square tile of value noise (made once per
// seed by cufund.worlds.materials); checker and brick are analytic.
#pragma once

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
float tile_lookup(const float* tile, int n, double a, double b);

// Deterministic value in [0, 1) per integer lattice cell (i, j).
float cell_hash(std::int64_t i, std::int64_t j, std::uint32_t seed);

// The pattern of `texture` at (a, b) [scale units]; `tile` (n x n) may be null for checker and none. Noise-based
// textures of different seeds read the same tile at seed-dependent offsets.
float pattern(Texture texture, double a, double b, const float* tile, int n, std::uint32_t seed);

}  // namespace cufund::render
