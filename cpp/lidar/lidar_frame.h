// One LiDAR frame in one call: the rays of a moving sensor (scan_rays), cast channel by channel in
// packets, and the returns the sensor reports (range window, dropout, range noise, intensity) with
// their noise-free world points.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
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

// The range model; the random draws come from the caller (one per ray, whether it returns or not). Every
// term past `n_reflectivity` is off by default (a null draw array), and with them off a frame is what it was
// before they existed, bit for bit.
struct RangeModel {
  double range_min = 0.0, range_max = 0.0;  // [m], returns outside are dropped
  const double* noise = nullptr;            // (n,) added to each range [m], the result clamped at 0; null: none
  const double* keep_draw = nullptr;        // (n,) a return is lost unless keep_draw[i] >= dropout; null: none
  double dropout = 0.0;
  const double* reflectivity = nullptr;  // per geometry id; null: 1 for all (intensity then float32)
  std::size_t n_reflectivity = 0;

  // Range noise growing with range and incidence: noise_z[i] (unit normal) x range_sigma(); null: none
  // (then `noise`, if any). Not both.
  const double* noise_z = nullptr;
  double noise_std = 0.0, noise_per_m = 0.0, incidence_noise = 0.0;  // [m], [m/m], [-]
  // Reflectivity- and incidence-dependent detection: a return is lost unless
  // detect_draw[i] < detection_probability(); null: every return detected.
  const double* detect_draw = nullptr;
  double max_range_at_10pct = std::numeric_limits<double>::infinity(), detection_softness = 0.1;  // [m], [-]
  // Mixed pixels: (n, 2) uniform draws; a return next to a depth edge of its channel (a neighbour in firing
  // order whose true range differs by more than mixed_edge) is mixed when draw[2i] < mixed_probability, its
  // range then r + draw[2i + 1] (r_neighbour - r) (the neighbour with the larger difference). null: none.
  const double* mixed_draw = nullptr;
  double mixed_probability = 0.0, mixed_edge = 0.3;  // [-], [m]
  // Timestamp jitter: added to each reported dt [s], the result clamped to [0, dt_max]; null: none.
  const double* dt_noise = nullptr;
  double dt_max = std::numeric_limits<double>::infinity();
  // Intensity noise: intensity x (1 + intensity_sigma() intensity_z[i]), clipped to [0, 1]; null: none.
  const double* intensity_z = nullptr;
  double intensity_noise = 0.0;
};

// cos of the incidence angle below which range noise stops growing (85 deg).
inline constexpr double kMinIncidenceCos = 0.08715574274765817;

// 1-sigma range noise [m] at true range r [m] and |cos incidence| c:
// (noise_std + noise_per_m r) (1 + incidence_noise (1 / max(c, cos 85 deg) - 1)).
double range_sigma(const RangeModel& model, double r, double c);

// Detection range [m] of a target of reflectivity rho at |cos incidence| c:
// max_range_at_10pct sqrt(rho c / 0.1).
double detection_range(const RangeModel& model, double rho, double c);

// Probability of a return at range r [m] from a target of reflectivity rho at |cos incidence| c: 1 up to
// r_max = detection_range(), 0 from r_max (1 + detection_softness), a smoothstep (C1) in between.
double detection_probability(const RangeModel& model, double r, double rho, double c);

// Relative 1-sigma intensity noise: intensity_noise (1 + (r / r_max)^2) with a finite max_range_at_10pct (the
// received power, proportional to rho c / r^2, against a fixed detector noise), else intensity_noise.
double intensity_sigma(const RangeModel& model, double r, double rho, double c);

// A cast frame: which rays returned, and what was hit (kept for write_returns).
struct CastFrame {
  std::vector<std::uint32_t> returns;       // ray indices of the valid returns, ascending
  std::vector<float> rays;                  // (n, 6) world rays (origin, direction)
  std::vector<float> t_hit, normals;        // (n,), (n, 3)
  std::vector<std::uint32_t> geometry;      // (n,)
  std::vector<std::uint32_t> order;         // (n,) ray indices by channel, then firing order
  std::uint32_t bad_geometry = kInvalidId;  // a hit geometry id without a reflectivity (else kInvalidId)
};

// Builds the rays at times t0 + t[i] (t0 [s]), casts them in coherent packets ordered by channel (then
// firing order) and selects the valid returns: scan_rays + RaycastScene::cast_rays ray for ray (see
// cast_rays_ordered on the last bits of distances).
void cast_frame(const RaycastScene& scene, const FrameRays& rays, double t0, const FrameKnots& knots,
                const RangeModel& model, int nthreads, CastFrame& out);

// Where write_returns puts the m = cast.returns.size() returns.
struct FrameReturns {
  double* dt;                 // (m,) firing time from the frame start [s] (with jitter: as reported)
  float* points_L;            // (m, 3) measured point in the sensor frame [m]
  double* ranges;             // (m,) measured range [m]
  double* intensity;          // (m,) reflectivity x |cos incidence| (x noise), clipped to [0, 1] (with reflectivities)
  float* intensity_f32;       // (m,) the same without reflectivities
  std::int32_t* channel;      // (m,)
  float* points_W;            // (m, 3) noise-free world hit [m]
  std::uint32_t* object_ids;  // (m,)
};

void write_returns(const FrameRays& rays, const RangeModel& model, const CastFrame& cast, const FrameReturns& out);

}  // namespace cufund::lidar
