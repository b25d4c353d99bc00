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
  float log_odds_hit = 0.85f;   // added to a voxel holding a beam end (p = 0.7)
  float log_odds_miss = -0.4f;  // added to a voxel a beam crosses (p = 0.4)
  float log_odds_min = -2.0f;   // clamping bounds
  float log_odds_max = 3.5f;
  float log_odds_occupied = 0.0f;                              // a voxel is occupied when its log-odds exceeds this
  double max_range = std::numeric_limits<double>::infinity();  // beams are cut here, the end free [m]
  // Casts one beam per distinct end voxel and scan (the scan's first point ending there) rather than one
  // per point. A beam cut at the grid's border or at max_range ends in the last voxel it reaches inside.
  // Hits are unchanged; free space is the part of the exact free set the kept beams cross (a subset), so
  // every log-odds is >= the per-point update's and the occupied voxels are a superset of its.
  bool merge_beams = false;
};

struct ScanStats {
  std::ptrdiff_t points = 0;          // points given
  std::ptrdiff_t nan_points = 0;      // skipped: a coordinate not finite
  std::ptrdiff_t outside = 0;         // beam end outside the grid: only the part inside marks free
  std::ptrdiff_t beyond_range = 0;    // longer than max_range: cut there, no hit
  std::ptrdiff_t beams = 0;           // beams cast: finite points whose beam crosses the grid (with
                                      // merge_beams, one per distinct end voxel)
  std::ptrdiff_t hit_voxels = 0;      // distinct voxels updated as hit
  std::ptrdiff_t free_voxels = 0;     // distinct voxels updated as free
  std::ptrdiff_t flipped_voxels = 0;  // voxels whose occupied state changed
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

  // One scan of a batch: n points p_W (n x 3) seen from origin_W.
  struct Scan {
    const double* p_W;
    Index n;
    std::array<double, 3> origin_W;
  };
  // Inserts the scans in order, each exactly as insert_scan does (the log-odds are the same as inserting
  // them one by one). Appends each voxel whose state differs from before the batch once to `flipped`, in
  // ascending order. The scans' beams are traversed in parallel, several scans at a time; the log-odds
  // updates run over voxel ranges in parallel, each voxel's scans in order. Returns the summed stats.
  ScanStats insert_scans(const std::vector<Scan>& scans, std::vector<Index>* flipped,
                         std::vector<std::uint8_t>* flipped_state, int nthreads = 1);

  // Sets voxels index[k] to log_odds_max (value[k] != 0) or log_odds_min; records flips as above.
  // Sets every voxel's log-odds from values (size() entries, e.g. a saved log_odds()), recording flips.
  void set_log_odds(const float* values, std::vector<Index>* flipped, std::vector<std::uint8_t>* flipped_state);
  void set_occupied(const std::vector<Index>& index, const std::vector<std::uint8_t>& value,
                    std::vector<Index>* flipped, std::vector<std::uint8_t>* flipped_state);

 private:
  // The part of a segment a -> b inside the grid, in voxel units: a + t d for t in [t0, t1].
  struct Clip {
    double a[3], d[3], t0, t1;
    Index cur[3], end[3];  // first and last voxel of the walk
  };
  // Clips segment a -> b (in voxel units: (p_W - origin_W) / resolution); false when it misses the grid.
  bool clip(const double* a, const double* b, Clip* c) const;
  // Visits the voxels a clipped segment crosses inside the grid, in order, as linear indices; with
  // `skip_end`, the voxel holding its end (when inside) is not visited.
  template <typename Visit>
  void traverse(const Clip& c, bool skip_end, Visit&& visit) const;
  // The end e of the beam to point p (cut at max_range; in voxel units) and the voxel holding it; true
  // when it is a hit (within range, inside the grid). Counts beyond_range and outside in stats.
  bool beam_end(const double* p, const double* origin_W, double* e, Index* voxel, ScanStats* stats) const;
  // Sets voxel i's log-odds, recording a change of its occupied state in flipped / state.
  void set(Index i, float value, std::vector<Index>* flipped, std::vector<std::uint8_t>* state);

  // What one scan does, whatever the grid holds: the distinct voxels holding a beam end (hit, a bitset)
  // and the voxels its beams cross (free, one byte per voxel; a voxel in both counts as hit), all clear
  // between scans, plus scratch kept so that its memory is not faulted in again every scan.
  struct ScanMarks {
    std::vector<std::uint64_t> hit, free_end;
    std::vector<std::uint8_t> free;  // 64 per word of `hit`
    std::vector<Index> free_ends;
    std::vector<std::uint8_t> use;
    ScanStats stats;
  };
  // Fills `marks` from one scan (its bitsets clear on entry); beams on `nthreads` threads.
  void mark(const Scan& scan, ScanMarks* marks, int nthreads) const;
  // Applies the marks of `count` scans in order to the log-odds, clears them, records net flips and
  // completes each scan's hit_voxels / free_voxels.
  void apply_marks(ScanMarks* const* marks, int count, std::vector<Index>* flipped,
                   std::vector<std::uint8_t>* flipped_state, int nthreads);

  GridGeometry geometry_;
  SensorModel model_;
  HugePageVector<float> log_odds_;
  // Scratch that a copy of the grid does not take (it is rebuilt on first use).
  template <typename T>
  struct Scratch : std::vector<T> {
    Scratch() = default;
    Scratch(const Scratch&) : std::vector<T>() {}
    Scratch& operator=(const Scratch&) { return *this; }
  };
  Scratch<ScanMarks> marks_;  // one per scan traversed concurrently
  struct ChunkFlips {
    std::vector<Index> index;
    std::vector<std::uint8_t> state;
    std::vector<Index> hit_voxels, free_voxels;  // per scan of the group
  };
  Scratch<ChunkFlips> chunk_flips_;  // per word range of the log-odds pass
};

}  // namespace cufund::esdf
