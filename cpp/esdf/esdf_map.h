// Occupancy grid plus the Euclidean signed distance field (ESDF) kept exactly up to date after
// every inserted scan, with batched trilinear distance and gradient queries.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <shared_mutex>
#include <vector>

#include "incremental_edt.h"
#include "occupancy_grid.h"

namespace cufund::esdf {

struct EsdfOptions {
  bool signed_distance = true;  // occupied voxels hold -(distance to the nearest free voxel centre)
  int nthreads = 0;             // <= 0: all hardware threads
};

struct EsdfUpdateStats {
  ScanStats scan;                // zero for set_occupied
  IncrementalEdtStats outside;   // the field outside obstacles (sites: occupied voxels)
  IncrementalEdtStats inside;    // the field inside obstacles (sites: free voxels); zero if unsigned
  double raycast_seconds = 0.0;  // wall time of the occupancy update (beam traversal, log-odds)
  double field_seconds = 0.0;    // wall time of the incremental distance-field update
};

// A reader-writer lock that a copy of its owner does not share (a copy gets its own, unlocked).
struct AccessLock {
  mutable std::shared_mutex mutex;
  AccessLock() = default;
  AccessLock(const AccessLock&) {}
  AccessLock& operator=(const AccessLock&) { return *this; }
};

class EsdfMap {
 public:
  using Index = std::ptrdiff_t;
  // The largest squared voxel distance the incremental transform stores exactly (int32).
  static constexpr double kMaxSquaredDiagonal = 2147483646.0;
  EsdfMap(const GridGeometry& geometry, const SensorModel& model, const EsdfOptions& options);

  const OccupancyGrid& occupancy() const { return grid_; }
  const GridGeometry& geometry() const { return grid_.geometry(); }
  const EsdfOptions& options() const { return options_; }

  // Inserts a point cloud (see OccupancyGrid::insert_scan) and updates the field incrementally.
  EsdfUpdateStats insert_scan(const double* p_W, Index n, const double* origin_W);
  // One scan of a batch: n points p_W (n x 3) seen from origin_W.
  using Scan = OccupancyGrid::Scan;
  // Inserts the scans in order, each exactly as insert_scan does (occupancy identical to inserting them
  // one by one), then updates the field once: the same map as one insert_scan per scan, with one
  // incremental field update instead of one per scan. The scan statistics are summed.
  EsdfUpdateStats insert_scans(const std::vector<Scan>& scans);
  // Forces voxels occupied / free (log-odds to the clamping bound) and updates the field incrementally.
  EsdfUpdateStats set_occupied(const std::vector<Index>& index, const std::vector<std::uint8_t>& value);
  // Sets every voxel's log-odds (occupancy().size() values, e.g. a saved log_odds()) and updates the
  // field: a map restored this way equals the saved one (occupancy and distances, bit for bit).
  EsdfUpdateStats set_log_odds(const float* values);
  // Recomputes the whole field from the occupancy (the incremental path must equal this bit for bit).
  void recompute();

  // Distance [m] at voxel i's centre: to the nearest occupied voxel centre for a free voxel; with
  // signed_distance, minus the distance to the nearest free voxel centre for an occupied one. +inf
  // when the grid has no occupied voxel (-inf inside when it has no free one).
  double voxel_distance(Index i) const;
  // Squared distances [voxels^2] of the outside and inside transforms (IncrementalEdt::kNoSite: none).
  std::vector<std::int32_t> outside_squared() const { return outside_.squared_distance(); }
  std::vector<std::int32_t> inside_squared() const;

  // Trilinear interpolation of the voxel-centre distances at n points p_W (n x 3): distance[k] [m] and,
  // if grad_W is not null, its exact gradient (n x 3) [m/m]. Points beyond the outermost voxel centres
  // take the value on the boundary (zero gradient along a clamped axis); a non-finite point gives NaN.
  void query(const double* p_W, Index n, double* distance, double* grad_W) const;

  // Callers that may run concurrently (the Python binding releases the GIL) hold this: exclusively to
  // insert, set or recompute; shared to read.
  std::shared_mutex& access_mutex() const { return access_.mutex; }

 private:
  EsdfUpdateStats apply(const std::vector<Index>& flipped, const std::vector<std::uint8_t>& state);

  OccupancyGrid grid_;
  EsdfOptions options_;
  IncrementalEdt outside_;
  std::optional<IncrementalEdt> inside_;  // empty when unsigned
  AccessLock access_;
};

}  // namespace cufund::esdf
