// Exact Euclidean distance transform of a voxel grid that is kept up to date as sites appear and
// disappear, touching only what changed. The separable transform is stored stage by stage (squared
// distance along z, then over y-z planes, then over the whole grid); a change of sites recomputes the
// z-columns that hold a changed voxel, then only the y-lines whose input changed, then only the
// x-lines whose input changed. Every line is computed by the same routine as a full recompute, so the
// result is bit-identical to one (the FIESTA idea of propagating only changes, made exact).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace cufund::esdf {

struct IncrementalEdtStats {
  std::ptrdiff_t changed_sites = 0;     // voxels whose site state toggled
  std::ptrdiff_t columns = 0;           // z-columns recomputed (stage 1)
  std::ptrdiff_t y_lines = 0;           // y-lines recomputed (stage 2)
  std::ptrdiff_t x_lines = 0;           // x-lines recomputed (stage 3)
  std::ptrdiff_t changed_distances = 0; // voxels whose final distance changed
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

  // Squared distance [voxels^2] from each voxel centre to the nearest site centre; kNoSite if none.
  const std::vector<std::int32_t>& squared_distance() const { return g3_; }

 private:
  // Stage computations for one line; each returns through `changed` the positions whose value changed.
  void column(Index c, std::vector<double>& buf, std::vector<Index>* changed);
  void y_line(Index l, std::vector<double>& f, std::vector<double>& d, std::vector<Index>& v,
              std::vector<double>& z, std::vector<Index>* changed);
  void x_line(Index l, std::vector<double>& f, std::vector<double>& d, std::vector<Index>& v,
              std::vector<double>& z, Index* changed);

  std::array<Index, 3> shape_;
  std::vector<std::uint8_t> sites_;
  std::vector<std::int32_t> g1_, g2_, g3_;
  std::vector<std::uint8_t> column_flag_, y_flag_, x_flag_;  // dedup marks, all zero between updates
};

}  // namespace cufund::esdf
