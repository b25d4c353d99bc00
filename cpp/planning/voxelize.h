// Surface voxelisation of triangle meshes: every voxel a triangle touches (exact separating-axis
// triangle/box overlap test, Akenine-Moller 2001), so that every surface point lies in a marked voxel.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "occupancy_grid.h"

namespace cufund::planning {

// Linear indices (i * ny + j) * nz + k, sorted and unique, of the grid voxels that n_triangles
// triangles (vertex indices into `vertices`, n_vertices x 3 [m]) overlap; closed boxes, so a triangle
// lying on a voxel face marks the voxels on both sides. Parts outside the grid are ignored. The caller
// checks indices are in range and coordinates finite.
std::vector<std::ptrdiff_t> voxelize_triangles(const esdf::GridGeometry& geometry, const double* vertices,
                                               std::ptrdiff_t n_vertices, const std::int64_t* triangles,
                                               std::ptrdiff_t n_triangles);

// True when the triangle (v0, v1, v2) overlaps the closed axis-aligned box centre c, half-size hs.
bool triangle_box_overlap(const double* c, const double* hs, const double* v0, const double* v1, const double* v2);

}  // namespace cufund::planning
