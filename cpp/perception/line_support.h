// Scoring candidate lines of a RANSAC over 2-D points (the tunnel detector's vertical planes): how much of
// each line its inliers cover, counted in bins along the line.
#pragma once

#include <cstddef>
#include <cstdint>

namespace cufund::perception {

// along: (n, k) row-major bin index of point i along candidate line j; inlier: (n, k) whether point i is
// an inlier of line j. Writes, per line j, the number of distinct bins among its inliers (covered[j]) and
// its inlier count (counts[j]).
void line_support(const std::int64_t* along, const bool* inlier, std::size_t n, std::size_t k, std::int64_t* covered,
                  std::int64_t* counts);

}  // namespace cufund::perception
