// DBSCAN (Ester et al. 1996) on 3-D points, with Open3D's labelling (PointCloud::ClusterDBSCAN): a point
// is a core point when at least min_points points (itself included) lie closer than eps; clusters are
// the connected groups of core points (within eps of each other) with the points near them, numbered
// 0, 1, ... in the order of their lowest-index core point; a border point near several clusters joins
// the lowest-numbered one; every other point is noise (-1). A uniform grid of eps cells finds the
// neighbours.
#pragma once

#include <cstddef>
#include <cstdint>

namespace cufund::perception {

// points: n x 3 (finite). labels: n. Returns the number of clusters.
std::int64_t dbscan(const double* points, std::size_t n, double eps, std::size_t min_points, std::int64_t* labels);

}  // namespace cufund::perception
