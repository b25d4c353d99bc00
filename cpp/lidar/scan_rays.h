// Rays of a LiDAR frame with motion: each ray leaves from the sensor pose at its own firing time,
// interpolated between pose knots (linear in position, spherical-linear in rotation).
#pragma once

#include <cstddef>

namespace cufund::lidar {

// knot_t: K >= 2 strictly increasing times [s]; knot_p: K x 3 positions p_WL [m]; knot_q: K x 4 unit
// quaternions q_WL [w, x, y, z] with consecutive signs aligned (dot >= 0). For ray i, at time t[i]
// (clamped to the knot span) with unit direction d_L[i] in the sensor frame, writes
// rays[6i..6i+6) = (p_WL(t), R_WL(t) d_L). Returns false (writing nothing) when K < 2.
bool scan_rays(const double* d_L, const double* t, std::size_t n, const double* knot_t, const double* knot_p,
               const double* knot_q, std::size_t k, float* rays);

}  // namespace cufund::lidar
