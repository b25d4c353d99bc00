// dbscan against a brute-force DBSCAN written from the definition (every pair's distance, clusters grown from the
// core points in index order), and on a cloud whose clusters are known by construction.
#include <gtest/gtest.h>

#include <cstdint>
#include <deque>
#include <random>
#include <vector>

#include "dbscan.h"

namespace cufund::perception {
namespace {

// Open3D's labelling, O(n^2): core points have >= min_points points (themselves included) closer than eps;
// clusters are numbered by their lowest-index core point; a border point takes the lowest-numbered cluster near it.
std::vector<std::int64_t> brute_force(const std::vector<double>& p, double eps, std::size_t min_points) {
  const std::size_t n = p.size() / 3;
  std::vector<std::vector<std::size_t>> near(n);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = 0; j < n; ++j) {
      const double dx = p[3 * i] - p[3 * j], dy = p[3 * i + 1] - p[3 * j + 1], dz = p[3 * i + 2] - p[3 * j + 2];
      if (dx * dx + dy * dy + dz * dz < eps * eps) near[i].push_back(j);
    }
  }
  std::vector<bool> core(n);
  for (std::size_t i = 0; i < n; ++i) core[i] = near[i].size() >= min_points;
  std::vector<std::int64_t> label(n, -1);
  std::int64_t clusters = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!core[i] || label[i] >= 0) continue;
    std::deque<std::size_t> queue{i};
    label[i] = clusters;
    while (!queue.empty()) {
      const std::size_t a = queue.front();
      queue.pop_front();
      for (std::size_t b : near[a]) {
        if (core[b] && label[b] < 0) {
          label[b] = clusters;
          queue.push_back(b);
        }
      }
    }
    ++clusters;
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (core[i]) continue;
    for (std::size_t j : near[i]) {
      if (core[j] && (label[i] < 0 || label[j] < label[i])) label[i] = label[j];
    }
  }
  return label;
}

TEST(Dbscan, MatchesTheBruteForceDefinitionOnRandomClouds) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const std::size_t n = 50 + 20 * static_cast<std::size_t>(trial);
    std::vector<double> p(3 * n);
    for (auto& x : p) x = u(rng);
    const double eps = 0.1 + 0.02 * (trial % 7);
    const std::size_t min_points = 1 + static_cast<std::size_t>(trial % 6);
    std::vector<std::int64_t> labels(n, 99);
    const std::int64_t clusters = dbscan(p.data(), n, eps, min_points, labels.data());
    const auto want = brute_force(p, eps, min_points);
    EXPECT_EQ(labels, want) << "trial " << trial;
    std::int64_t max_label = -1;
    for (auto l : want) max_label = std::max(max_label, l);
    EXPECT_EQ(clusters, max_label + 1);
  }
}

TEST(Dbscan, TwoSeparatedBlobsAndAnOutlier) {
  std::vector<double> p;
  for (int i = 0; i < 10; ++i) p.insert(p.end(), {0.01 * i, 0.0, 0.0});        // cluster 0: a row 1 cm apart
  for (int i = 0; i < 10; ++i) p.insert(p.end(), {5.0, 5.0 + 0.01 * i, 1.0});  // cluster 1
  p.insert(p.end(), {-3.0, 2.0, 0.5});                                         // noise
  std::vector<std::int64_t> labels(21);
  EXPECT_EQ(dbscan(p.data(), 21, 0.015, 2, labels.data()), 2);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(labels[i], 0);
  for (int i = 10; i < 20; ++i) EXPECT_EQ(labels[i], 1);
  EXPECT_EQ(labels[20], -1);
  EXPECT_EQ(dbscan(p.data(), 0, 0.015, 2, labels.data()), 0);  // no points: no clusters
}

}  // namespace
}  // namespace cufund::perception
