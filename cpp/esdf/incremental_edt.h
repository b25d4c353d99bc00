// Exact Euclidean distance transform of a voxel grid that is kept up to date as sites appear and
// disappear, touching only what changed (the FIESTA idea of propagating changes, made exact). The
// separable transform is stored stage by stage as integer squared voxel distances: along z (stage 1),
// then over each x-slab (stage 2, along y), then over the grid (stage 3, along x). A change of sites
// recomputes the z-columns holding a changed voxel; each later stage visits only the lines whose input
// changed, and there only the outputs a changed input can reach. An input that shrank lowers outputs
// to its parabola (a min, like an insertion wavefront); an input that grew forces an exact recompute
// of the outputs it was nearest to, from an input window proven wide enough. Values are integers and
// every step is exact, so the result is identical to a full recompute, not merely close.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "huge_page_allocator.h"

namespace cufund::esdf {

struct IncrementalEdtStats {
  std::ptrdiff_t changed_sites = 0;      // voxels whose site state toggled
  std::ptrdiff_t columns = 0;            // z-columns recomputed (stage 1)
  std::ptrdiff_t y_lines = 0;            // y-lines recomputed (stage 2)
  std::ptrdiff_t x_lines = 0;            // x-lines recomputed (stage 3)
  std::ptrdiff_t changed_distances = 0;  // voxels whose final distance changed
};

class IncrementalEdt {
 public:
  using Index = std::ptrdiff_t;
  // Squared distance (in voxels^2) of a voxel with no site in the grid.
  static constexpr std::int32_t kNoSite = std::numeric_limits<std::int32_t>::max();

  // An [nx][ny][nz] grid (C order, z fastest) with no sites.
  explicit IncrementalEdt(const std::array<Index, 3>& shape);

  const std::array<Index, 3>& shape() const { return shape_; }
  Index size() const { return shape_[0] * shape_[1] * shape_[2]; }
  const std::vector<std::uint8_t>& sites() const { return sites_; }

  // Replaces all sites and recomputes every stage.
  void reset(const std::uint8_t* sites, int nthreads);
  // Recomputes every stage from the current sites (what `update` must reproduce exactly).
  void recompute(int nthreads);
  // Sets site[i] = value[k] for i = index[k] and updates the transform incrementally.
  // Indices must be in [0, size()); repeated indices take the last value.
  IncrementalEdtStats update(const std::vector<Index>& index, const std::vector<std::uint8_t>& value, int nthreads);

  // Squared distance [voxels^2] from voxel i = (ix * ny + iy) * nz + iz to the nearest site centre;
  // kNoSite if there is none.
  std::int32_t squared_distance_at(Index i) const {
    const Index nx = shape_[0], ny = shape_[1], nz = shape_[2];
    const Index ix = i / (ny * nz), iy = (i / nz) % ny, iz = i % nz;
    return g3_[static_cast<std::size_t>((iz * ny + iy) * nx + ix)];
  }
  // All of them, in the grid's C order (a copy).
  std::vector<std::int32_t> squared_distance() const;

 private:
  struct Scratch;
  // Lines of a stage whose input changed, with the changed positions: line `line` changed at
  // positions[begin..end) (sorted, distinct).
  struct LineWork {
    Index line, begin, end;
  };
  // A changed input of the next stage: line, position and min(old value, new value).
  struct Change {
    Index line;
    std::int32_t pos, low;
  };
  struct Position {
    std::int32_t pos, low;
  };
  struct Work {
    std::vector<LineWork> lines;  // sorted by line
    std::vector<Position> positions;
  };
  using Changes = std::vector<std::vector<Change>>;  // per chunk of work

  // Stage-2 line iz * nx + ix runs along y; stage-3 line iz * ny + iy runs along x.
  struct LineView {
    Index n;                 // length
    const std::int32_t* in;  // input, contiguous
    std::int32_t* out;       // output, stride out_stride
    Index out_stride;
  };
  LineView view(int stage, Index line);

  // Stage 1 for column c = ix * ny + iy; appends (stage-2 line, position iy) where g1 changed.
  void column(Index c, std::vector<double>& buf, std::vector<Change>* changed);
  // Full stage-2/3 pass over all lines, in groups of neighbouring lines that share cache lines;
  // returns how many outputs changed.
  Index full_pass(int stage, int nthreads);
  // Updates the outputs of one line that its changed inputs (positions with low = min(old, new input))
  // can reach. Appends the changes of the output (stage 2) and counts changed voxels.
  void update_line(int stage, const LineWork& work, const std::vector<Position>& positions, Scratch& s,
                   std::vector<Change>* changed, Index* n_changed);
  // Stages 2 and 3 of an update, one z-slice at a time: a slice's stage-2 lines, then the stage-3
  // lines their output changes reach, all in the same slice of g2 and g3 (640 kB for 400 x 400),
  // which stays in cache between the two. Slices run in parallel.
  void update_slices(const Work& work, int nthreads, Index* x_lines, Index* n_changed);
  // Prefetches the inputs and outputs at a line's changed positions.
  void prefetch_line(int stage, const LineWork& work, const std::vector<Position>& positions);
  // Merges per-chunk (line, position) lists into per-line sorted positions, emptying the lists.
  void merge(Changes& changes, Work& out);

  std::array<Index, 3> shape_;
  std::vector<std::uint8_t> sites_;
  // Stage outputs, each laid out so that the next stage reads its lines contiguously:
  // g1 [ix][iz][iy] (y fastest), g2 and g3 [iz][iy][ix] (x fastest).
  HugePageVector<std::int32_t> g1_, g2_, g3_;
  // Merge scratch, one entry per line of the largest stage: -1 / unused between updates.
  std::vector<Index> merge_slot_;
  // Buffers of `update`, kept between calls so that their memory is not faulted in again each time.
  Changes changes_;
  Work columns_, work_;
};

}  // namespace cufund::esdf
