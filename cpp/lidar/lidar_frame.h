// One LiDAR frame in one call: the rays of a moving sensor (scan_rays), cast channel by channel in
// packets, and the returns the sensor reports (range window, dropout, range noise, intensity) with
// their noise-free world points.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "raycast_scene.h"

namespace cufund::lidar {

// The frame's rays in the sensor frame, n of each.
struct FrameRays {
  const double* d_L = nullptr;            // (n, 3) unit directions
  const double* t = nullptr;              // (n,) firing time from the frame start [s]
  const std::int32_t* channel = nullptr;  // (n,) laser channel
  std::size_t n = 0;
};

// Sensor poses over the frame (see scan_rays): k >= 2 knots, strictly increasing times.
struct FrameKnots {
  const double* t = nullptr;  // (k,) absolute [s]
  const double* p = nullptr;  // (k, 3) p_WL [m]
  const double* q = nullptr;  // (k, 4) q_WL [w, x, y, z], consecutive signs aligned
  std::size_t k = 0;
};

// The range model; the random draws come from the caller (one per ray, whether it returns or not).
struct RangeModel {
  double range_min = 0.0, range_max = 0.0;  // [m], returns outside are dropped
  const double* noise = nullptr;            // (n,) added to each range [m], the result clamped at 0; null: none
  const double* keep_draw = nullptr;        // (n,) a return is lost unless keep_draw[i] >= dropout; null: none
  double dropout = 0.0;
  const double* reflectivity = nullptr;  // per geometry id; null: 1 for all (intensity then float32)
  std::size_t n_reflectivity = 0;
};

// A cast frame: which rays returned, and what was hit (kept for write_returns).
struct CastFrame {
  std::vector<std::uint32_t> returns;       // ray indices of the valid returns, ascending
  std::vector<float> rays;                  // (n, 6) world rays (origin, direction)
  std::vector<float> t_hit, normals;        // (n,), (n, 3)
  std::vector<std::uint32_t> geometry;      // (n,)
  std::uint32_t bad_geometry = kInvalidId;  // a hit geometry id without a reflectivity (else kInvalidId)
};

// Builds the rays at times t0 + t[i] (t0 [s]), casts them in coherent packets ordered by channel (then
// firing order) and selects the valid returns: scan_rays + RaycastScene::cast_rays ray for ray (see
// cast_rays_ordered on the last bits of distances).
void cast_frame(const RaycastScene& scene, const FrameRays& rays, double t0, const FrameKnots& knots,
                const RangeModel& model, int nthreads, CastFrame& out);

// Where write_returns puts the m = cast.returns.size() returns.
struct FrameReturns {
  double* dt;                 // (m,) firing time from the frame start [s]
  float* points_L;            // (m, 3) measured point in the sensor frame [m]
  double* ranges;             // (m,) measured range [m]
  double* intensity;          // (m,) reflectivity x |cos incidence|, clipped to [0, 1] (with reflectivities)
  float* intensity_f32;       // (m,) the same without reflectivities
  std::int32_t* channel;      // (m,)
  float* points_W;            // (m, 3) noise-free world hit [m]
  std::uint32_t* object_ids;  // (m,)
};

void write_returns(const FrameRays& rays, const RangeModel& model, const CastFrame& cast, const FrameReturns& out);

}  // namespace cufund::lidar
