#include "textures.h"

namespace cufund::render {

float pattern(Texture texture, double a, double b, const float* tile, int n, std::uint32_t seed) {
  if (texture != Texture::kChecker) {
    // one shared noise tile (it stays in cache): each seed reads it from its own place
    double da, db;
    seed_shift(seed, da, db);
    a += da;
    b += db;
  }
  return pattern_shifted(texture, a, b, tile, n, seed);
}

}  // namespace cufund::render
