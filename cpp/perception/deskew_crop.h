// A LiDAR scan moved to the world point by point (deskewed) and cropped, for the tunnel detector
// (cufund.perception.TunnelDetector): each point, measured in the sensor frame at its firing time, is
// moved with the sensor poses at the two knots around that time and the two results blended linearly.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace cufund::perception {

struct DeskewKnots {
  std::size_t segments = 0;      // K: K + 1 knots evenly over [0, span]
  double span = 0.0;             // [s] > 0
  const double* p_WL = nullptr;  // (K + 1, 3) [m]
  const double* R_WL = nullptr;  // (K + 1, 3, 3) row-major
};

struct CropBox {
  double max_range = 0.0;           // points farther from the sensor are dropped [m]
  double z_min = 0.0, z_max = 0.0;  // points outside [z_min, z_max] are dropped [m]
  double tall_z = 0.0;              // points above this are flagged (walls, poles) [m]
  double column_cell = 0.1;         // edge of the x-y columns keyed [m]
};

struct CroppedScan {
  std::vector<double> points_W;        // (m, 3) [m]
  std::vector<double> rays_W;          // (m, 3) unit direction from the sensor to each point
  std::vector<std::int64_t> columns;   // (m,) x-y column key (cufund.perception.detection.column_keys)
  std::vector<std::int64_t> new_tall;  // sorted column keys above tall_z in this scan, not in the given set
};

// points_L: rows 0, stride, 2 stride, ... of an (n, 3) scan [m]; dt: (n,) firing times from the scan's
// start [s], the same rows taken. Keeps the points within max_range of the sensor (and further than
// 1e-6 m) and inside [z_min, z_max], in scan order, except those in a tall column: one of the sorted
// `tall` keys (n_tall of them) or one where a kept point of this scan lies above tall_z (reported in
// new_tall when not already in `tall`).
void deskew_crop(const float* points_L, const double* dt, std::size_t n, std::size_t stride, const DeskewKnots& knots,
                 const CropBox& box, const std::int64_t* tall, std::size_t n_tall, CroppedScan& out);

}  // namespace cufund::perception
