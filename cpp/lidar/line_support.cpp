#include "line_support.h"

#include <algorithm>
#include <vector>

namespace cufund::lidar {

void line_support(const std::int64_t* along, const bool* inlier, std::size_t n, std::size_t k, std::int64_t* covered,
                  std::int64_t* counts) {
  std::vector<std::int64_t> bins;
  bins.reserve(n);
  for (std::size_t j = 0; j < k; ++j) {
    bins.clear();
    for (std::size_t i = 0; i < n; ++i) {
      if (inlier[i * k + j]) bins.push_back(along[i * k + j]);
    }
    counts[j] = static_cast<std::int64_t>(bins.size());
    std::sort(bins.begin(), bins.end());
    covered[j] = static_cast<std::int64_t>(std::unique(bins.begin(), bins.end()) - bins.begin());
  }
}

}  // namespace cufund::lidar
