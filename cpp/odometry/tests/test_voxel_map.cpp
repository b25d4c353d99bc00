// Voxel map and point-to-plane terms against brute force and finite differences.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <map>
#include <random>
#include <tuple>
#include <vector>

#include "imu_propagation.h"
#include "voxel_map.h"

namespace cufund::odometry {
namespace {

TEST(VoxelDownsample, CentroidsEqualBruteForceGrouping) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  std::vector<double> pts(3 * 2000);
  for (auto& x : pts) x = u(rng);
  const double v = 0.7;
  const auto out = voxel_downsample(pts.data(), 2000, v);
  std::map<std::tuple<long, long, long>, std::pair<Eigen::Vector3d, int>> groups;
  for (std::size_t i = 0; i < 2000; ++i) {
    auto key = std::make_tuple(static_cast<long>(std::floor(pts[3 * i] / v)),
                               static_cast<long>(std::floor(pts[3 * i + 1] / v)),
                               static_cast<long>(std::floor(pts[3 * i + 2] / v)));
    auto& g = groups[key];
    if (g.second == 0) g.first.setZero();
    g.first += Eigen::Vector3d(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
    ++g.second;
  }
  ASSERT_EQ(out.size(), 3 * groups.size());
  for (std::size_t j = 0; j < groups.size(); ++j) {
    const Eigen::Vector3d c(out[3 * j], out[3 * j + 1], out[3 * j + 2]);
    auto key = std::make_tuple(static_cast<long>(std::floor(c.x() / v)), static_cast<long>(std::floor(c.y() / v)),
                               static_cast<long>(std::floor(c.z() / v)));
    const auto& g = groups.at(key);
    EXPECT_LT((g.first / g.second - c).norm(), 1e-12);
  }
}

TEST(VoxelMap, KnnEqualsBruteForceOverStoredPoints) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-4.0, 4.0);
  std::vector<double> pts(3 * 5000);
  for (auto& x : pts) x = u(rng);
  VoxelMap map(0.5, 10, 0.05, 100.0, 1000000);
  map.insert(pts.data(), 5000, Eigen::Vector3d::Zero());
  const auto stored = map.points();
  ASSERT_EQ(stored.size(), 3 * map.size());
  ASSERT_LT(map.size(), 5000u);  // the per-voxel cap and spacing dropped some
  const int k = 5;
  const std::size_t q = 200;
  std::vector<double> queries(3 * q), nb(3 * q * k), d2(q * k);
  for (auto& x : queries) x = u(rng);
  map.knn(queries.data(), q, k, 0.4, nb.data(), d2.data(), 2);
  for (std::size_t i = 0; i < q; ++i) {
    std::vector<double> all;
    for (std::size_t j = 0; j < map.size(); ++j) {
      const double d = (Eigen::Map<const Eigen::Vector3d>(stored.data() + 3 * j) -
                        Eigen::Map<const Eigen::Vector3d>(queries.data() + 3 * i))
                           .squaredNorm();
      if (d <= 0.16) all.push_back(d);
    }
    std::sort(all.begin(), all.end());
    for (int j = 0; j < k; ++j) {
      if (j < static_cast<int>(all.size()))
        EXPECT_DOUBLE_EQ(d2[i * k + j], all[j]);
      else
        EXPECT_TRUE(std::isinf(d2[i * k + j]));
    }
  }
}

TEST(VoxelMap, SearchesStayExactAfterEvictionsCompactTheMap) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-6.0, 6.0);
  VoxelMap map(0.5, 8, 0.05, 4.0, 600);
  for (int round = 0; round < 5; ++round) {
    std::vector<double> pts(3 * 4000);
    for (auto& x : pts) x = u(rng);
    map.insert(pts.data(), 4000, Eigen::Vector3d(round - 2.0, 0.5 * round, 0.0));
  }
  ASSERT_LE(map.voxel_count(), 600u);
  const auto stored = map.points();
  ASSERT_EQ(stored.size(), 3 * map.size());
  std::vector<double> queries(3 * 100), nb(3 * 100 * 4), d2(100 * 4);
  for (auto& x : queries) x = u(rng) / 3.0;
  map.knn(queries.data(), 100, 4, 0.5, nb.data(), d2.data(), 2);
  for (std::size_t i = 0; i < 100; ++i) {
    std::vector<double> all;
    for (std::size_t j = 0; j < map.size(); ++j) {
      const double d = (Eigen::Map<const Eigen::Vector3d>(stored.data() + 3 * j) -
                        Eigen::Map<const Eigen::Vector3d>(queries.data() + 3 * i))
                           .squaredNorm();
      if (d <= 0.25) all.push_back(d);
    }
    std::sort(all.begin(), all.end());
    for (std::size_t j = 0; j < 4; ++j) {
      if (j < all.size())
        EXPECT_DOUBLE_EQ(d2[i * 4 + j], all[j]);
      else
        EXPECT_TRUE(std::isinf(d2[i * 4 + j]));
    }
  }
}

TEST(VoxelMap, EvictsByDistanceAndBySize) {
  std::vector<double> pts;
  for (int i = 0; i < 100; ++i) pts.insert(pts.end(), {static_cast<double>(i), 0.0, 0.0});
  VoxelMap map(1.0, 5, 0.0, 10.0, 1000);
  map.insert(pts.data(), 100, Eigen::Vector3d::Zero());
  EXPECT_EQ(map.voxel_count(), 10u);  // centres 0.5 .. 9.5
  VoxelMap small(1.0, 5, 0.0, 1000.0, 7);
  small.insert(pts.data(), 100, Eigen::Vector3d(50, 0, 0));
  const auto kept = small.points();
  ASSERT_EQ(kept.size(), 21u);
  for (std::size_t j = 0; j < 7; ++j) EXPECT_LE(std::abs(kept[3 * j] - 50.0), 4.0);  // voxel centres within 3.5 m
}

TEST(VoxelMap, PointToPlaneGradientMatchesFiniteDifferences) {
  // Map: three orthogonal walls; scan: points near them seen from a perturbed pose.
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(0.2, 3.8);
  std::vector<double> wall;
  for (int i = 0; i < 20000; ++i) {
    const double a = u(rng), b = u(rng);
    const int side = i % 3;
    if (side == 0) wall.insert(wall.end(), {a, b, 0.0});
    if (side == 1) wall.insert(wall.end(), {a, 0.0, b});
    if (side == 2) wall.insert(wall.end(), {0.0, a, b});
  }
  VoxelMap map(0.5, 20, 0.02, 100.0, 1000000);
  map.insert(wall.data(), wall.size() / 3, Eigen::Vector3d::Zero());
  std::vector<double> scan;
  for (int i = 0; i < 600; ++i) {
    const double a = 0.5 + u(rng) * 0.7, b = 0.5 + u(rng) * 0.7;
    if (i % 3 == 0) scan.insert(scan.end(), {a, b, 0.0});
    if (i % 3 == 1) scan.insert(scan.end(), {a, 0.0, b});
    if (i % 3 == 2) scan.insert(scan.end(), {0.0, a, b});
  }
  PlaneParams prm;
  prm.robust = Robust::kNone;
  prm.neighbours = 8;
  prm.max_neighbour_distance = 0.5;
  const Eigen::Matrix3d R = so3_exp(Eigen::Vector3d(0.01, -0.02, 0.015));
  const Eigen::Vector3d t(0.03, -0.02, 0.04);
  const PlaneTerms terms = map.point_to_plane(scan.data(), scan.size() / 3, R, t, prm, 2);
  ASSERT_GT(terms.inliers, 500u);
  // d cost / d xi = 2 b, H positive definite (three walls constrain all six directions).
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> es(terms.H);
  EXPECT_GT(es.eigenvalues()[0], 0.0);
  for (int j = 0; j < 6; ++j) {
    Eigen::Matrix<double, 6, 1> xi = Eigen::Matrix<double, 6, 1>::Zero();
    xi[j] = 1e-6;
    auto cost_at = [&](double s) {
      const Eigen::Matrix3d Rp = R * so3_exp(s * xi.head<3>());
      const Eigen::Vector3d tp = t + R * (s * xi.tail<3>());
      return map.point_to_plane(scan.data(), scan.size() / 3, Rp, tp, prm, 1).cost;
    };
    const double fd = (cost_at(1.0) - cost_at(-1.0)) / 2e-6;
    EXPECT_NEAR(fd, 2.0 * terms.b[j], 1e-4 * (1.0 + std::abs(fd)));
  }
  // A Gauss-Newton step from H and b brings the scan back onto the walls.
  const Eigen::Matrix<double, 6, 1> step = -terms.H.ldlt().solve(terms.b);
  const PlaneTerms after =
      map.point_to_plane(scan.data(), scan.size() / 3, R * so3_exp(step.head<3>()), t + R * step.tail<3>(), prm, 2);
  EXPECT_LT(after.cost, 0.05 * terms.cost);
}

}  // namespace
}  // namespace cufund::odometry
