// A LiDAR frame made ready for registration in one pass: deskewed to its end (deskew.h), returns closer than
// min_range dropped (the airframe), downsampled to the map's insertion voxel, that downsampled again to the
// registration voxel, and both moved to the IMU frame. Equal to deskew, a range filter and voxel_downsample
// called in turn, without the intermediate arrays.
#pragma once

#include <vector>

#include "deskew.h"

namespace cufund::odometry {

struct PreparedScan {
  std::vector<double> insert_I;  // (m, 3) centroids of the insert_voxel grid (in L), in the IMU frame
  std::vector<double> scan_I;    // (s, 3) centroids of insert_I's L-frame points on the scan_voxel grid, IMU frame
};

PreparedScan prepare_scan(const float* points_L, const double* t_points, std::size_t n, const Trajectory& traj,
                          double t_ref, const Eigen::Isometry3d& T_BI, const Eigen::Isometry3d& T_BL, double min_range,
                          double insert_voxel, double scan_voxel, int threads);

}  // namespace cufund::odometry
