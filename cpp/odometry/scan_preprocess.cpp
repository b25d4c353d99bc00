#include "scan_preprocess.h"

#include <cmath>

#include "voxel_map.h"

namespace cufund::odometry {

namespace {

std::vector<double> to_imu(const std::vector<double>& points_L, const Eigen::Isometry3d& T_IL) {
  std::vector<double> out(points_L.size());
  const Eigen::Matrix3d R = T_IL.linear();
  const Eigen::Vector3d t = T_IL.translation();
  for (std::size_t i = 0; i < points_L.size() / 3; ++i) {
    Eigen::Map<Eigen::Vector3d>(out.data() + 3 * i) =
        R * Eigen::Map<const Eigen::Vector3d>(points_L.data() + 3 * i) + t;
  }
  return out;
}

}  // namespace

PreparedScan prepare_scan(const float* points_L, const double* t_points, std::size_t n, const Trajectory& traj,
                          double t_ref, const Eigen::Isometry3d& T_BI, const Eigen::Isometry3d& T_BL, double min_range,
                          double insert_voxel, double scan_voxel, int threads) {
  std::vector<double> deskewed(3 * n);
  deskew(points_L, t_points, n, traj, t_ref, T_BI, T_BL, deskewed.data(), threads);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double* p = deskewed.data() + 3 * i;
    if (!(std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) >= min_range)) continue;
    if (kept != i) std::copy(p, p + 3, deskewed.data() + 3 * kept);
    ++kept;
  }
  const std::vector<double> insert_L = voxel_downsample(deskewed.data(), kept, insert_voxel);
  const std::vector<double> scan_L = voxel_downsample(insert_L.data(), insert_L.size() / 3, scan_voxel);
  const Eigen::Isometry3d T_IL = T_BI.inverse() * T_BL;
  return {to_imu(insert_L, T_IL), to_imu(scan_L, T_IL)};
}

}  // namespace cufund::odometry
