// Certified clearance queries on an ESDF map: a lower bound on the distance from a point to any
// obstacle surface lying inside an occupied voxel, and a sphere-traced segment (motion) check.
#pragma once

#include <array>
#include <cstddef>

#include "esdf_map.h"

namespace cufund::planning {

using Vec3 = std::array<double, 3>;

// A non-owning view of an EsdfMap (the caller keeps the map alive and holds its read lock), or of a
// static field: an array of voxel-centre distances (e.g. from euclidean_distance_transform).
//
// clearance(p) = max over the 8 voxel centres c around p of (D(c) - |p - c|) - sqrt(3)/2 * h, where
// D(c) >= 0 is the exact distance from c to the nearest occupied voxel centre (the map's outside
// field) and h the resolution. D is 1-Lipschitz, so the max is a lower bound on the distance from p to
// every occupied voxel centre, and a surface point inside an occupied voxel is at most sqrt(3)/2 * h
// from that voxel's centre: clearance(p) <= the true distance from p to such a surface. Points
// outside the grid (or not finite) get -inf (unknown space is not flyable); +inf when nothing is
// occupied.
class ClearanceMap {
 public:
  explicit ClearanceMap(const esdf::EsdfMap& map);
  // distances: shape[0] * shape[1] * shape[2] values, voxel (i, j, k) at (i * ny + j) * nz + k, the
  // distance [m] from each voxel centre to the nearest occupied voxel centre (<= 0 or -inf at occupied
  // voxels, +inf everywhere when nothing is occupied). Not copied: the caller keeps it alive.
  ClearanceMap(const esdf::GridGeometry& geometry, const double* distances);

  double clearance(const Vec3& p) const;
  // True when every point of the segment p0 -> p1 is at least `radius` from every surface inside an
  // occupied voxel, certified by sphere tracing from both ends (a ball of radius clearance(q) - radius
  // around a traced point q is free, by the Lipschitz bound); a step shorter than min_step() counts
  // as blocked, so a segment must clear the radius by that much somewhere along each stretch.
  bool segment_free(const Vec3& p0, const Vec3& p1, double radius) const;
  // The smallest clearance along the segment, sampled every `spacing` [m] (ends included).
  double segment_min_clearance(const Vec3& p0, const Vec3& p1, double spacing) const;

  bool inside(const Vec3& p) const;
  double min_step() const { return 0.02 * geometry_.resolution; }
  const esdf::GridGeometry& geometry() const { return geometry_; }
  // Voxel centre and linear index helpers.
  Vec3 centre(std::ptrdiff_t i, std::ptrdiff_t j, std::ptrdiff_t k) const;
  // Distance D at a voxel centre [m], >= 0 (0 for occupied voxels); +inf when nothing is occupied.
  double centre_distance(std::ptrdiff_t linear) const;

 private:
  const esdf::EsdfMap* map_ = nullptr;
  const double* distances_ = nullptr;
  esdf::GridGeometry geometry_;
  double half_diagonal_;
};

}  // namespace cufund::planning
