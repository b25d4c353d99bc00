// Bounded voxel occupancy grid with log-odds updates by ray casting point clouds from the sensor
// origin: free along each beam, occupied at its end, clamped (OctoMap's sensor model).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "huge_page_allocator.h"

namespace cufund::esdf {

struct GridGeometry {
  std::array<double, 3> origin_W{0.0, 0.0, 0.0};  // world position of the grid's minimum corner [m]
  std::array<std::ptrdiff_t, 3> shape{1, 1, 1};   // voxels along x, y, z; voxel (i, j, k) is
                                                  // data[(i * ny + j) * nz + k]
  double resolution = 0.1;                        // voxel edge length [m]
};

struct SensorModel {
  float log_odds_hit = 0.85f;      // added to a voxel holding a beam end (p = 0.7)
  float log_odds_miss = -0.4f;     // added to a voxel a beam crosses (p = 0.4)
  float log_odds_min = -2.0f;      // clamping bounds
  float log_odds_max = 3.5f;
  float log_odds_occupied = 0.0f;  // a voxel is occupied when its log-odds exceeds this
  double max_range = std::numeric_limits<double>::infinity();  // beams are cut here, the end free [m]
};

struct ScanStats {
  std::ptrdiff_t points = 0;         // points given
  std::ptrdiff_t nan_points = 0;     // skipped: a coordinate not finite
  std::ptrdiff_t outside = 0;        // beam end outside the grid: only the part inside marks free
  std::ptrdiff_t beyond_range = 0;   // longer than max_range: cut there, no hit
  std::ptrdiff_t hit_voxels = 0;     // distinct voxels updated as hit
  std::ptrdiff_t free_voxels = 0;    // distinct voxels updated as free
  std::ptrdiff_t flipped_voxels = 0; // voxels whose occupied state changed
};

class OccupancyGrid {
 public:
  using Index = std::ptrdiff_t;
  OccupancyGrid(const GridGeometry& geometry, const SensorModel& model);

  const GridGeometry& geometry() const { return geometry_; }
  const SensorModel& model() const { return model_; }
  Index size() const { return static_cast<Index>(log_odds_.size()); }
  const HugePageVector<float>& log_odds() const { return log_odds_; }
  bool occupied(Index i) const { return log_odds_[static_cast<std::size_t>(i)] > model_.log_odds_occupied; }

  // Inserts n points p_W (n x 3, world frame) seen from sensor origin_W (3). Appends the voxels whose
  // occupied state changed to `flipped` (with their new state in `flipped_state`). Points with a
  // non-finite coordinate are skipped; origin_W must be finite (checked by the caller). Beams are traversed
  // on up to `nthreads` threads (0: all); the result does not depend on the thread count.
  ScanStats insert_scan(const double* p_W, Index n, const double* origin_W, std::vector<Index>* flipped,
                        std::vector<std::uint8_t>* flipped_state, int nthreads = 1);

  // Sets voxels index[k] to log_odds_max (value[k] != 0) or log_odds_min; records flips as above.
  // Sets every voxel's log-odds from values (size() entries, e.g. a saved log_odds()), recording flips.
  void set_log_odds(const float* values, std::vector<Index>* flipped, std::vector<std::uint8_t>* flipped_state);
  void set_occupied(const std::vector<Index>& index, const std::vector<std::uint8_t>& value,
                    std::vector<Index>* flipped, std::vector<std::uint8_t>* flipped_state);

 private:
  // Visits the voxels a segment a_W -> b_W crosses inside the grid, in order, as linear indices;
  // with `skip_end`, the voxel holding b_W (when inside) is not visited.
  template <typename Visit>
  void traverse(const double* a_W, const double* b_W, bool skip_end, Visit&& visit) const;
  // Sets voxel i's log-odds, recording a change of its occupied state in flipped / state.
  void set(Index i, float value, std::vector<Index>* flipped, std::vector<std::uint8_t>* state);
  // Adds delta, clamped to log_odds_max (hit) or log_odds_min (miss), recording a flip like set.
  void apply(Index i, float delta, bool hit, std::vector<Index>* flipped, std::vector<std::uint8_t>* state);

  GridGeometry geometry_;
  SensorModel model_;
  HugePageVector<float> log_odds_;
  // Per-scan marks, one bit per voxel (small enough to stay in cache while beams are walked); all
  // clear between scans.
  std::vector<std::uint64_t> hit_bits_, free_bits_;
  // Per-scan buffers, kept so that their memory is not faulted in again on every scan.
  std::vector<std::uint8_t> use_;
  std::vector<double> ends_;
  std::vector<Index> hits_;
  struct ChunkFlips {
    std::vector<Index> index;
    std::vector<std::uint8_t> state;
    Index free_voxels = 0;
  };
  std::vector<ChunkFlips> chunk_flips_;  // per word range of the free-voxel pass
};

}  // namespace cufund::esdf
