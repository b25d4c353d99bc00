// Voxel downsampling and an incremental hashed voxel map with point-to-plane registration terms.
//
// The map keeps at most `max_points_per_voxel` points per cubic voxel (a new point closer than
// `min_point_distance` to a kept one is dropped), evicts voxels farther than `max_distance` from the vehicle
// and, past `max_voxels`, the farthest ones. Neighbour searches look at the 27 voxels around a query, so every
// point within one voxel size of the query is found (search radii are capped at the voxel size).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace cufund::odometry {

// Voxel key of a point; false if a coordinate is outside the +-2^20 voxel index range.
bool voxel_key(const Eigen::Vector3d& p, double inv_voxel, std::int64_t& key);

// Centroid of the points in each occupied voxel, in the order the voxels are first seen. points: (n, 3).
std::vector<double> voxel_downsample(const double* points, std::size_t n, double voxel);

enum class Robust { kNone = 0, kHuber = 1, kCauchy = 2 };

struct PlaneParams {
  int neighbours = 5;                   // points fitted per plane
  double max_neighbour_distance = 1.0;  // [m], capped at the voxel size
  double max_plane_rms = 0.05;          // RMS of the neighbours' distances to their plane [m]
  double max_residual = 0.5;            // point-to-plane distances beyond this are outliers [m]
  Robust robust = Robust::kHuber;
  double robust_scale = 0.05;  // [m]
  double sigma = 0.02;         // residual standard deviation: H and b are divided by sigma^2
};

struct PlaneTerms {
  // Per point (n): valid flag, residual r = n.(R q + t - c), plane normal (3), robust weight.
  std::vector<std::uint8_t> valid;
  std::vector<double> residual, normal, weight;
  // Sums over valid points of w J^T J / sigma^2 and w J^T r / sigma^2, J = d r / d xi for T_WI Exp(xi),
  // xi = [rotation, translation] (GTSAM's Pose3 tangent); cost = sum w r^2 / sigma^2.
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
  double cost = 0.0;
  std::size_t inliers = 0;
};

// Point-to-plane terms of points_I (n, 3) placed by (R_WI, t_W) against given planes (n, 4) where fitted[i].
PlaneTerms plane_terms(const double* points_I, const double* planes, const std::uint8_t* fitted, std::size_t n,
                       const Eigen::Matrix3d& R_WI, const Eigen::Vector3d& t_W, const PlaneParams& params, int threads);

class VoxelMap {
 public:
  VoxelMap(double voxel_size, int max_points_per_voxel, double min_point_distance, double max_distance,
           std::size_t max_voxels);

  // Adds world points (n, 3), then evicts around `origin`. Returns the number of points kept.
  std::size_t insert(const double* points_W, std::size_t n, const Eigen::Vector3d& origin);
  void evict(const Eigen::Vector3d& origin);
  void clear();

  std::size_t size() const { return points_; }
  std::size_t voxel_count() const { return keys_.size(); }
  double voxel_size() const { return voxel_; }
  std::vector<double> points() const;  // every stored point, (size(), 3)

  static constexpr int kMaxNeighbours = 64;  // the largest k of knn and of PlaneParams::neighbours

  // k nearest stored points within max_distance (<= voxel size) of each query (q, 3): idx-free output
  // neighbours (q, k, 3) and squared distances (q, k) sorted ascending, +inf where fewer were found.
  void knn(const double* queries, std::size_t q, int k, double max_distance, double* neighbours, double* dist2,
           int threads) const;

  // Fits a plane to the neighbours of each point of points_I (n, 3) placed by (R_WI, t_W): valid (n,) and
  // planes (n, 4) [normal, offset] with normal . x + offset = 0 in the world.
  void fit_planes(const double* points_I, std::size_t n, const Eigen::Matrix3d& R_WI, const Eigen::Vector3d& t_W,
                  const PlaneParams& params, std::uint8_t* valid, double* planes, int threads) const;

  // Point-to-plane terms of points_I (n, 3, in the frame whose world pose is R_WI, t_W): fit_planes, then
  // plane_terms.
  PlaneTerms point_to_plane(const double* points_I, std::size_t n, const Eigen::Matrix3d& R_WI,
                            const Eigen::Vector3d& t_W, const PlaneParams& params, int threads) const;

 private:
  // Up to k nearest (ascending); returns how many were found.
  int nearest(const Eigen::Vector3d& query, int k, double max_d2, Eigen::Vector3d* out, double* d2) const;
  // Dense index of the voxel with `key`, or -1.
  std::int32_t find(std::int64_t key) const;
  void table_insert(std::int64_t key, std::int32_t index);
  void rebuild_table(std::size_t capacity);

  double voxel_, inv_voxel_, min_d2_, max_distance_;
  int max_per_voxel_;
  std::size_t max_voxels_;
  std::size_t points_ = 0;
  // Voxels in insertion order: key, point count, centre, and max_per_voxel_ point slots each.
  std::vector<std::int64_t> keys_;
  std::vector<int> counts_;
  std::vector<Eigen::Vector3d> centres_;
  std::vector<double> slots_;
  // Open-addressing hash (linear probing) from key to dense index; capacity a power of two.
  std::vector<std::int64_t> table_keys_;
  std::vector<std::int32_t> table_index_;
  std::size_t table_mask_ = 0;
  unsigned table_shift_ = 64;
};

}  // namespace cufund::odometry
