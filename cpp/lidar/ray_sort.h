// Ray reordering for coherence: permutations of a batch of rays (ox, oy, oz, dx, dy, dz rows) that
// put rays likely to visit the same part of a BVH next to each other, so that they share packets and
// find the nodes and triangles they need still in cache (Garanzha & Loop's and Aila & Karras's ray
// sorting). A permutation only decides which rays are traced together and when: it never changes a
// ray's result.
#pragma once

#include <cstddef>
#include <cstdint>

namespace cufund::lidar {

// Largest batch direction_tile_order accepts.
inline constexpr std::size_t kMaxTileRays = 1024;

// Orders the rays [begin, end) (at most kMaxTileRays) along a Morton curve over their directions
// (octahedral map, 8 bits per axis over the batch's own angular extent), so that 8 consecutive rays
// form a compact angular tile. Meant for rays that share an origin: a scan delivered column by column
// (8 channels of one column = a thin line) then fills packets with 2 x 4 neighbourhoods.
// order[k] is the offset from `begin` of the k-th ray.
void direction_tile_order(const float* rays, std::size_t begin, std::size_t end, std::uint16_t* order);

// Which point of a ray spatial_order sorts by.
enum class RayKey {
  kHeading,      // o + reach * d / |d|, reach = half the scene's largest side: rays that head the
                 //   same way from nearby origins pack into coherent packets (best on BVHs that
                 //   fit in cache)
  kBoxCrossing,  // where the ray leaves the scene's box when it starts inside (the far end of the
                 //   stretch that can hit anything), where it enters when it starts outside and
                 //   points at it, else its origin: rays that end in the same part of the scene are
                 //   traced together, so its nodes and triangles stay in cache (best on large BVHs)
};

// Orders all n rays by the Morton code (6 bits per axis, over the box around the scene and the
// origins) of their `key` point, given the box [scene_lo, scene_hi] holding the scene (inverted,
// lo > hi, for an empty scene: every ray then keys by its origin). Rays next to each other in the
// order travel through the same part of the scene; within a cell they keep their input order.
// A stable radix sort, split into blocks over the thread pool (nthreads <= 0: all): the same order
// for any thread count. Rays must be finite with non-zero directions; n < 2^32. The calling thread
// keeps 16 bytes per ray of scratch for its next call.
void spatial_order(const float* rays, std::size_t n, const float* scene_lo, const float* scene_hi, RayKey key,
                   std::uint32_t* order, int nthreads);

}  // namespace cufund::lidar
