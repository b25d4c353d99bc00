#include "ray_sort.h"

#include "thread_pool.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#if defined(__SSE__)
#include <xmmintrin.h>
#endif

namespace cufund::lidar {

namespace {

// Spreads the low 16 bits of v to the even bits.
inline std::uint32_t spread_by_1(std::uint32_t v) {
  v &= 0x0000FFFFu;
  v = (v | (v << 8)) & 0x00FF00FFu;
  v = (v | (v << 4)) & 0x0F0F0F0Fu;
  v = (v | (v << 2)) & 0x33333333u;
  v = (v | (v << 1)) & 0x55555555u;
  return v;
}

// Rays per block of spatial_order's parallel passes (one work item of the thread pool).
constexpr std::size_t kBlock = std::size_t{1} << 16;
// Bits per axis of the keyed point's Morton code (64^3 cells: finer keys measured no faster),
// sorted by two radix passes of 9 bits (512 buckets: few enough write streams to stay in cache).
constexpr int kAxisBits = 6;
constexpr int kDigitBits = 9;
constexpr int kPasses = 2;
constexpr std::uint32_t kDigits = 1u << kDigitBits;

// Turns per-block digit counts (hist[block * digits + digit]) into the first output slot of each
// (block, digit): all of digit 0 in block order, then digit 1, ... (a stable counting sort).
void exclusive_offsets(std::vector<std::uint32_t>& hist, std::size_t blocks, std::uint32_t digits) {
  std::uint32_t sum = 0;
  for (std::uint32_t d = 0; d < digits; ++d) {
    for (std::size_t b = 0; b < blocks; ++b) {
      const std::uint32_t c = hist[b * digits + d];
      hist[b * digits + d] = sum;
      sum += c;
    }
  }
}

// Counts the digits (bits [shift, shift + kDigitBits) of the key half) of e[begin, end) into h.
void count_digits(const std::uint64_t* e, std::size_t begin, std::size_t end, int shift, std::uint32_t* h) {
  std::fill(h, h + kDigits, 0u);
  for (std::size_t i = begin; i < end; ++i) ++h[(e[i] >> shift) & (kDigits - 1)];
}

// Moves e[begin, end) to out[slot[digit]++]; with `ray_only`, writes the low (ray) half to ray_out instead.
void scatter_digits(const std::uint64_t* e, std::size_t begin, std::size_t end, int shift, std::uint32_t* slot,
                    std::uint64_t* out, std::uint32_t* ray_out) {
  if (ray_out) {
    for (std::size_t i = begin; i < end; ++i) {
      ray_out[slot[(e[i] >> shift) & (kDigits - 1)]++] = static_cast<std::uint32_t>(e[i]);
    }
  } else {
    for (std::size_t i = begin; i < end; ++i) out[slot[(e[i] >> shift) & (kDigits - 1)]++] = e[i];
  }
}

// Each kAxisBits-bit value with its bits spread to every third bit (one axis of a 3D Morton code).
struct Spread3Table {
  std::uint32_t v[1 << kAxisBits];
  constexpr Spread3Table() : v() {
    for (std::uint32_t i = 0; i < (1u << kAxisBits); ++i) {
      std::uint32_t r = 0;
      for (int bit = 0; bit < kAxisBits; ++bit) r |= ((i >> bit) & 1u) << (3 * bit);
      v[i] = r;
    }
  }
};
constexpr Spread3Table kSpread3;

// min2 = b < a ? b : a and max2 = a < b ? b : a (a NaN b gives a), without branches: the compiler
// turns these selects into jumps, which mispredict on random rays.
#if defined(__SSE__)
inline float min2(float a, float b) { return _mm_cvtss_f32(_mm_min_ss(_mm_set_ss(b), _mm_set_ss(a))); }
inline float max2(float a, float b) { return _mm_cvtss_f32(_mm_max_ss(_mm_set_ss(b), _mm_set_ss(a))); }
#else
inline float min2(float a, float b) { return b < a ? b : a; }
inline float max2(float a, float b) { return a < b ? b : a; }
#endif

// The cell of coordinate x on an axis of 2^kAxisBits cells from lo (NaN: cell 0).
inline std::uint32_t cell(float x, float lo, float scale) {
  constexpr float kMax = static_cast<float>((1 << kAxisBits) - 1);
  const float q = min2(max2(0.0f, (x - lo) * scale), kMax);
  return static_cast<std::uint32_t>(static_cast<int>(q));
}

// Where ray r meets the box [lo, hi] that holds the scene: where it leaves the box when it starts
// inside (the far end of the stretch that can hit anything), where it enters when it starts outside
// and points at it, else its origin.
inline std::array<float, 3> box_point(const float* r, const float* lo, const float* hi) {
  float t_in = -INFINITY, t_out = INFINITY;
  for (int k = 0; k < 3; ++k) {
    const float inv = 1.0f / r[3 + k];  // +-inf for a zero component: that slab never ends
    const float a = (lo[k] - r[k]) * inv, b = (hi[k] - r[k]) * inv;
    t_in = max2(t_in, min2(a, b));  // a NaN (origin on a plane) leaves the bound as it was
    t_out = min2(t_out, max2(a, b));
  }
  // Inside: t_in <= 0 <= t_out. Outside and pointing at the box: 0 < t_in <= t_out.
  const float t = t_in <= 0.0f ? max2(t_out, 0.0f) : (t_in <= t_out ? t_in : 0.0f);
  return {r[0] + t * r[3], r[1] + t * r[4], r[2] + t * r[5]};
}

// Where ray r heads: the point `reach` along it.
inline std::array<float, 3> heading_point(const float* r, float reach) {
  const float s = reach / std::sqrt(r[3] * r[3] + r[4] * r[4] + r[5] * r[5]);
  return {r[0] + s * r[3], r[1] + s * r[4], r[2] + s * r[5]};
}

// Morton key of point(ray) for each ray in [begin, end), quantised to kAxisBits per axis in the
// cube [q0, q0 + 2^kAxisBits / scale)^3, paired with the ray's index.
template <typename Point>
void point_keys(const float* rays, std::size_t begin, std::size_t end, const Point& point, const float* q0, float scale,
                std::uint64_t* e) {
  for (std::size_t i = begin; i < end; ++i) {
    const std::array<float, 3> p = point(rays + 6 * i);
    const std::uint32_t c = kSpread3.v[cell(p[0], q0[0], scale)] | (kSpread3.v[cell(p[1], q0[1], scale)] << 1) |
                            (kSpread3.v[cell(p[2], q0[2], scale)] << 2);
    e[i] = (std::uint64_t{c} << 32) | i;
  }
}

}  // namespace

void direction_tile_order(const float* rays, std::size_t begin, std::size_t end, std::uint16_t* order) {
  const std::size_t m = end - begin;
  float uv[2][kMaxTileRays];
  float lo[2] = {2.0f, 2.0f}, hi[2] = {-2.0f, -2.0f};
  for (std::size_t i = 0; i < m; ++i) {
    const float* d = rays + 6 * (begin + i) + 3;
    const float inv = 1.0f / (std::abs(d[0]) + std::abs(d[1]) + std::abs(d[2]));
    float u = d[0] * inv, v = d[1] * inv;
    if (d[2] < 0.0f) {
      const float uu = (1.0f - std::abs(v)) * (u >= 0.0f ? 1.0f : -1.0f);
      v = (1.0f - std::abs(u)) * (v >= 0.0f ? 1.0f : -1.0f);
      u = uu;
    }
    uv[0][i] = u;
    uv[1][i] = v;
    lo[0] = std::min(lo[0], u);
    hi[0] = std::max(hi[0], u);
    lo[1] = std::min(lo[1], v);
    hi[1] = std::max(hi[1], v);
  }
  // One scale for both axes keeps tiles square in angle.
  const float extent = std::max(hi[0] - lo[0], hi[1] - lo[1]);
  const float scale = extent > 0.0f ? 255.0f / extent : 0.0f;
  std::uint16_t key[2][kMaxTileRays];
  std::uint16_t idx[2][kMaxTileRays];
  for (std::size_t i = 0; i < m; ++i) {
    const auto qu = static_cast<std::uint32_t>(std::min((uv[0][i] - lo[0]) * scale, 255.0f));
    const auto qv = static_cast<std::uint32_t>(std::min((uv[1][i] - lo[1]) * scale, 255.0f));
    key[0][i] = static_cast<std::uint16_t>(spread_by_1(qu) | (spread_by_1(qv) << 1));
    idx[0][i] = static_cast<std::uint16_t>(i);
  }
  // Two 8-bit radix passes, all in cache.
  int src = 0;
  for (int shift = 0; shift < 16; shift += 8) {
    std::uint32_t count[256] = {};
    for (std::size_t i = 0; i < m; ++i) ++count[(key[src][i] >> shift) & 255u];
    std::uint32_t sum = 0;
    for (auto& c : count) {
      const std::uint32_t t = c;
      c = sum;
      sum += t;
    }
    for (std::size_t i = 0; i < m; ++i) {
      const std::uint32_t dst = count[(key[src][i] >> shift) & 255u]++;
      key[1 - src][dst] = key[src][i];
      idx[1 - src][dst] = idx[src][i];
    }
    src = 1 - src;
  }
  std::copy(idx[src], idx[src] + m, order);
}

void spatial_order(const float* rays, std::size_t n, const float* scene_lo, const float* scene_hi, RayKey key,
                   std::uint32_t* order, int nthreads) {
  if (n == 0) return;
  const std::size_t blocks = (n + kBlock - 1) / kBlock;
  const auto rays_n = static_cast<std::ptrdiff_t>(n);  // parallel_chunks counts in ptrdiff_t
  const bool empty = !(scene_lo[0] <= scene_hi[0] && scene_lo[1] <= scene_hi[1] && scene_lo[2] <= scene_hi[2]);
  float reach = 0.0f;  // kHeading: half the scene
  for (int k = 0; k < 3 && !empty; ++k) reach = std::max(reach, 0.5f * (scene_hi[k] - scene_lo[k]));
  if (empty) key = RayKey::kHeading;  // with reach 0: the origins

  // The keyed points lie on the scene's box, within reach of an origin or at an origin: quantise
  // in the box around the scene and the origins grown by reach.
  std::vector<std::array<float, 6>> boxes(blocks);
  parallel_chunks(rays_n, kBlock, nthreads, [&](std::size_t begin, std::size_t end, std::size_t b) {
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (std::size_t i = begin; i < end; ++i) {
      for (int k = 0; k < 3; ++k) {
        lo[k] = std::min(lo[k], rays[6 * i + k]);
        hi[k] = std::max(hi[k], rays[6 * i + k]);
      }
    }
    boxes[b] = {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]};
  });
  const float grow = key == RayKey::kHeading ? reach : 0.0f;
  float q0[3], extent = 0.0f;
  for (int k = 0; k < 3; ++k) {
    float hi = empty ? -INFINITY : scene_hi[k];
    q0[k] = empty ? INFINITY : scene_lo[k];
    for (const auto& box : boxes) {
      q0[k] = std::min(q0[k], box[k] - grow);
      hi = std::max(hi, box[3 + k] + grow);
    }
    extent = std::max(extent, hi - q0[k]);
  }
  // One scale for all axes: cubic cells.
  constexpr float kCells = static_cast<float>(1 << kAxisBits);
  const float scale = extent > 0.0f && std::isfinite(extent) ? kCells / extent : 0.0f;

  // (key << 32 | ray) pairs, sorted by key in kPasses stable counting passes, each split into blocks.
  // Reused by the calling thread's next sort: fresh pages would cost more than the sort itself.
  thread_local std::vector<std::uint64_t> scratch;
  if (scratch.size() < 2 * n) scratch.resize(2 * n);
  std::uint64_t* src = scratch.data();
  std::uint64_t* dst = src + n;
  parallel_chunks(rays_n, kBlock, nthreads, [&](std::size_t begin, std::size_t end, std::size_t) {
    if (key == RayKey::kHeading) {
      auto along = [&](const float* r) { return heading_point(r, reach); };
      point_keys(rays, begin, end, along, q0, scale, src);
    } else {
      auto crossing = [&](const float* r) { return box_point(r, scene_lo, scene_hi); };
      point_keys(rays, begin, end, crossing, q0, scale, src);
    }
  });
  std::vector<std::uint32_t> slots(blocks * kDigits);
  for (int pass = 0; pass < kPasses; ++pass) {
    const int shift = 32 + pass * kDigitBits;
    parallel_chunks(rays_n, kBlock, nthreads, [&](std::size_t begin, std::size_t end, std::size_t b) {
      count_digits(src, begin, end, shift, &slots[b * kDigits]);
    });
    exclusive_offsets(slots, blocks, kDigits);
    std::uint32_t* ray_out = pass == kPasses - 1 ? order : nullptr;
    parallel_chunks(rays_n, kBlock, nthreads, [&](std::size_t begin, std::size_t end, std::size_t b) {
      scatter_digits(src, begin, end, shift, &slots[b * kDigits], dst, ray_out);
    });
    std::swap(src, dst);
  }
}

}  // namespace cufund::lidar
