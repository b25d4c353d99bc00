// One sensor on each of N vehicles, cast in one call: a fixed set of sensor-frame ray directions (a
// pinhole depth camera's pixels, a LiDAR scan pattern's frame) leaves from every vehicle's sensor pose
// into one RaycastScene, and, optionally, into the other vehicles' oriented boxes (each sensor sees
// every box but its own). Threads run over vehicles; each vehicle's rays are cast on one thread in the
// 8-wide coherent packets of RaycastScene::cast_rays(..., RayOrder::kCoherent), so a vehicle's hits
// are bit for bit those of that call on the rays batch_rays writes.
#pragma once

#include <cstddef>
#include <cstdint>

#include "raycast_scene.h"

namespace cufund::lidar {

// Where the N sensors are: p_WS (N, 3) [m] and q_WS (N, 4) [w, x, y, z] (normalised here).
struct SensorPoses {
  const double* p_WS = nullptr;
  const double* q_WS = nullptr;
  std::size_t n = 0;
};

// The vehicles' oriented boxes, seen by every sensor but its own: centres p_WB (M, 3) [m], attitudes q_WB
// (M, 4) [w, x, y, z] and half extents (M, 3) [m] along the box's own axes. owner[i] (N,) is the box of
// sensor i's own vehicle (-1: none). m == 0: no boxes.
struct VehicleBoxes {
  const double* p_WB = nullptr;
  const double* q_WB = nullptr;
  const double* half_extents = nullptr;
  std::size_t m = 0;
  const std::int64_t* owner = nullptr;
};

// What a ray reports: its distance t along its direction (a range for unit directions, the depth along
// the optical axis for a pinhole's (1, -x_n, -y_n) directions). A hit closer than range_min or farther
// than range_max, and a miss, report miss_value. With std or per_m > 0, a valid return becomes
// max(t + sigma(t) z, 0), sigma(t) = std + per_m t, z a standard normal; with dropout > 0 it is lost
// (miss_value) with that probability. The draws of vehicle i in frame `frame` come from a stream keyed by
// (seed + i, frame): the same on any number of threads, and vehicle i of a batch seeded s draws what a batch of
// one seeded s + i does (Gymnasium's seeding of vector envs).
struct BatchRangeModel {
  float range_min = 0.0f;
  float range_max = 1e30f;
  float miss_value = 1e30f;
  double noise_std = 0.0;
  double noise_per_m = 0.0;
  double dropout = 0.0;
  std::uint64_t seed = 0;
  std::uint64_t frame = 0;
};

enum class BatchStatus {
  kOk,
  kNonFinitePose,       // index: the sensor
  kZeroQuaternion,      // index: the sensor
  kNonFiniteDirection,  // index: the direction
  kZeroDirection,       // index: the direction
  kBadBox,              // index: the box (non-finite pose, zero quaternion, negative or non-finite extent)
  kBadOwner,            // index: the sensor (owner not in [-1, M))
};

struct BatchResult {
  BatchStatus status = BatchStatus::kOk;
  std::size_t index = 0;
};

// Writes the (N, R, 6) float32 rays of the batch: ray (i, r) leaves p_WS[i] along R(q_WS[i]) d_S[r].
BatchResult batch_rays(const SensorPoses& poses, const float* d_S, std::size_t r, float* rays, int nthreads = 0);

// Casts the N x R rays of batch_rays and writes out (N, R) float32 per BatchRangeModel. nthreads <= 0: every core.
// Input is checked first; on a bad pose, direction or box nothing is written.
BatchResult batch_cast(const RaycastScene& scene, const SensorPoses& poses, const float* d_S, std::size_t r,
                       const VehicleBoxes& boxes, const BatchRangeModel& model, float* out, int nthreads = 0);

// Applies the range model to sensor i's distances t (r) in place: out of range and misses -> miss_value, noise and
// dropout from the stream of (seed + i, frame). batch_cast's last stage, shared by other casters.
void apply_range_model(const BatchRangeModel& model, std::size_t i, float* t, std::size_t r);

// batch_cast's checks of the poses and the r directions (kOk, or the first bad one).
BatchResult check_sensor_input(const SensorPoses& poses, const float* d_S, std::size_t r);

// Distance along (o + t d) to the first point of the oriented box (centre c, unit quaternion q [w, x, y, z],
// half extents h), 0 when o is inside, +inf when the ray misses it (slab test in the box's frame).
double ray_box_distance(const double o[3], const double d[3], const double c[3], const double q[4], const double h[3]);

}  // namespace cufund::lidar
