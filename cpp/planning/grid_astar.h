// Deterministic A* over the voxel centres of an ESDF map with a clearance constraint, and greedy
// line-of-sight shortcutting of its result. The default global path search where repeatability
// matters more than optimality: the same map, start, goal and options give the same path, always.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <memory>
#include <vector>

#include "clearance.h"

namespace cufund::planning {

enum class PathStatus : int {
  kFound = 0,
  kStartBlocked = 1,    // the start is outside the map or closer than the radius to an obstacle
  kGoalBlocked = 2,     // the same for the goal
  kNoPath = 3,          // every reachable voxel was expanded
  kExpansionLimit = 4,  // max_expansions reached first
};

struct AStarOptions {
  double radius = 0.2;                      // required clearance [m] of every point of the path
  std::ptrdiff_t max_expansions = 5000000;  // stop after this many node expansions
  bool shortcut = true;                     // greedy line-of-sight shortcutting of the voxel path
  double heuristic_weight = 1.0;            // >= 1: weighted A* (f = g + w h), at most w times the grid optimum
  // Height band [m]: voxels whose centre lies outside [z_min, z_max] are not nodes (e.g. a flight band above
  // ground the map has not observed yet). The start and goal points themselves may lie outside it.
  double z_min = -std::numeric_limits<double>::infinity();
  double z_max = std::numeric_limits<double>::infinity();
};

struct AStarResult {
  PathStatus status = PathStatus::kNoPath;
  std::vector<Vec3> path;         // start, waypoints, goal [m] (empty unless found)
  double length = 0.0;            // [m] of `path`
  std::ptrdiff_t expansions = 0;  // nodes expanded
  std::ptrdiff_t clearance_queries = 0;
};

// A* on the 26-connected grid of voxel centres. A voxel is a node when its clearance is >= radius;
// an edge when the segment between the centres is free (ClearanceMap::segment_free, cheap when both
// ends clear the radius by half the edge length). The start and goal points connect to those of the
// 27 voxels around them that a free segment reaches. Ties are broken by the smaller heuristic, then
// the smaller linear index, so the result does not depend on anything but the inputs. Buffers are
// kept between searches on the same grid shape.
class GridAStar {
 public:
  AStarResult plan(const ClearanceMap& map, const Vec3& start, const Vec3& goal, const AStarOptions& options);

 private:
  double node_clearance(const ClearanceMap& map, std::ptrdiff_t linear, AStarResult& result);
  // Per-voxel buffers from calloc / malloc: a large grid costs no page until a search touches it (a
  // std::vector would write every byte up front). Entries are valid where stamp_ == generation_.
  struct Free {
    void operator()(void* p) const { std::free(p); }
  };
  template <typename T>
  using Buffer = std::unique_ptr<T[], Free>;
  std::ptrdiff_t size_ = 0;
  Buffer<std::uint32_t> stamp_;
  Buffer<float> g_;
  Buffer<float> clearance_;      // NaN: not yet queried in this search
  Buffer<std::int64_t> parent_;  // -1: joined to the start point
  Buffer<std::uint8_t> closed_;
  std::uint32_t generation_ = 0;
};

// Greedy shortcutting: from each kept point, jump to the farthest later point a free segment reaches.
// The first and last points are kept; the result is free wherever the input was.
std::vector<Vec3> shortcut_path(const ClearanceMap& map, const std::vector<Vec3>& path, double radius);

// String pulling of a free path: segments are split to at most `max_segment` [m], then `iterations` sweeps
// (fewer once nothing moves) move each interior vertex towards the closest point of the segment joining its
// neighbours, by the largest of 1, 1/2, 1/4, 1/8 of the way for which both its segments stay free at the
// radius and its height does not move further out of [z_min, z_max]; then greedy shortcutting. Each move
// never lengthens the path (the length through a point is convex in it), and the result is free wherever
// the input was. Deterministic.
std::vector<Vec3> relax_path(const ClearanceMap& map, const std::vector<Vec3>& path, double radius,
                             double z_min = -std::numeric_limits<double>::infinity(),
                             double z_max = std::numeric_limits<double>::infinity(), double max_segment = 0.5,
                             int iterations = 30);

double path_length(const std::vector<Vec3>& path);

}  // namespace cufund::planning
