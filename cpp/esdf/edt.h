// Exact Euclidean distance transform of a boolean voxel grid (Felzenszwalb & Huttenlocher):
// separable, linear time, multithreaded on the shared thread pool.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace cufund::esdf {

enum class EdtStatus {
  kOk,
  kBadShape,      // a dimension < 1
  kBadVoxelSize,  // a voxel size not finite or <= 0
};

struct EdtOptions {
  std::array<double, 3> voxel_size{1.0, 1.0, 1.0};  // per axis, same order as the shape [m]
  bool signed_distance = false;                     // negative inside: -(distance to the nearest non-site voxel centre)
  int nthreads = 0;                                 // <= 0: all hardware threads
};

// out[i] = distance from voxel i's centre to the nearest voxel centre with sites[i] != 0, for a C-order
// grid of `shape` (use leading 1s for 2-D or 1-D grids); +inf when there is no site. With
// signed_distance, site voxels instead hold minus the distance to the nearest non-site voxel.
// Instantiated for float and double; `out` must hold shape[0] * shape[1] * shape[2] elements.
template <typename T>
EdtStatus euclidean_distance_transform(const std::uint8_t* sites, const std::array<std::ptrdiff_t, 3>& shape,
                                       const EdtOptions& options, T* out);

}  // namespace cufund::esdf
