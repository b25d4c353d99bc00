// Places a LiDAR frame in the world: each point, measured in the LiDAR frame at its own firing time, is
// moved with the body pose interpolated at that time and the LiDAR extrinsic (motion deskewing).
#pragma once

#include <array>
#include <cstddef>
#include <vector>

namespace cufund::esdf {

// Body poses sampled in time: stamps t[k] [s] (strictly ascending), positions p_W[3k..3k+2] [m] and
// quaternions q_WB[4k..4k+3] [w, x, y, z] (any non-zero norm), k < n, n >= 1.
struct PoseKnots {
  const double* t = nullptr;
  const double* p_W = nullptr;
  const double* q_WB = nullptr;
  std::ptrdiff_t n = 0;
};

// A rigid transform T_AB (p_A = R_AB p_B + t_AB), R row-major.
struct RigidTransform {
  std::array<double, 9> R{1, 0, 0, 0, 1, 0, 0, 0, 1};
  std::array<double, 3> t{0, 0, 0};
};

// The body pose at time t: linear in position, normalised linear in the quaternion (the short way
// round), clamped at the first and last knot (cufund.geometry.interpolate_poses).
RigidTransform body_pose_at(const PoseKnots& knots, double t);
// The same, with `*hint` the interval (knots i, i + 1) to try first; updated to the one used.
RigidTransform body_pose_at(const PoseKnots& knots, double t, std::ptrdiff_t* hint);

// points_W[3k..] = p_WB(t[k]) + R_WB(t[k]) (R_BL points_L[3k..] + t_BL) for k < n. A non-finite point
// stays non-finite (the map skips it).
void place_points(const PoseKnots& knots, const RigidTransform& T_BL, const double* points_L, const double* t,
                  std::ptrdiff_t n, double* points_W);

// One LiDAR frame: n points points_L[3k..3k+2] [m, LiDAR frame] fired at t[k] [s]; its scan origin is the
// LiDAR's position at t_origin [s].
struct LidarFrame {
  const double* points_L = nullptr;
  const double* t = nullptr;
  std::ptrdiff_t n = 0;
  double t_origin = 0.0;
};

// A frame placed in the world: its points (place_points) and its scan origin p_WB + R_WB t_BL at t_origin.
struct PlacedFrame {
  std::vector<double> points_W;  // 3n
  std::array<double, 3> origin_W{};
};

// Places `count` frames, each on its own, in parallel on up to `nthreads` threads of the shared pool (<= 0: all);
// the result does not depend on the threads.
std::vector<PlacedFrame> place_frames(const PoseKnots& knots, const RigidTransform& T_BL, const LidarFrame* frames,
                                      std::size_t count, int nthreads);

}  // namespace cufund::esdf
