#include "line_support.h"

#include <algorithm>
#include <limits>
#include <vector>

namespace cufund::perception {

void line_support(const std::int64_t* along, const bool* inlier, std::size_t n, std::size_t k, std::int64_t* covered,
                  std::int64_t* counts) {
  std::fill(covered, covered + k, 0);
  std::fill(counts, counts + k, 0);
  std::int64_t lo = std::numeric_limits<std::int64_t>::max(), hi = std::numeric_limits<std::int64_t>::min();
  for (std::size_t e = 0; e < n * k; ++e) {
    if (inlier[e]) {
      lo = std::min(lo, along[e]);
      hi = std::max(hi, along[e]);
    }
  }
  if (lo > hi) return;  // no inliers
  const auto bins = static_cast<std::uint64_t>(hi) - static_cast<std::uint64_t>(lo) + 1;
  if (bins <= (std::uint64_t{1} << 22) / std::max<std::size_t>(k, 1)) {
    // A few bins (the points span a few metres of 5 cm bins): mark each line's bins in one pass over the rows.
    std::vector<unsigned char> seen(k * bins, 0);
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t j = 0; j < k; ++j) {
        const std::size_t e = i * k + j;
        if (!inlier[e]) continue;
        ++counts[j];
        unsigned char& s = seen[j * bins + static_cast<std::size_t>(along[e] - lo)];
        covered[j] += s == 0;
        s = 1;
      }
    }
    return;
  }
  std::vector<std::int64_t> line;
  line.reserve(n);
  for (std::size_t j = 0; j < k; ++j) {
    line.clear();
    for (std::size_t i = 0; i < n; ++i) {
      if (inlier[i * k + j]) line.push_back(along[i * k + j]);
    }
    counts[j] = static_cast<std::int64_t>(line.size());
    std::sort(line.begin(), line.end());
    covered[j] = static_cast<std::int64_t>(std::unique(line.begin(), line.end()) - line.begin());
  }
}

}  // namespace cufund::perception
