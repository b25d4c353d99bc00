#include "allocation.h"

#include <algorithm>
#include <cmath>

namespace cufund {

ControlAllocator::ControlAllocator(const QuadrotorParams& params)
    : A_(allocation_matrix(params)),
      A_inv_(allocation_matrix_inverse(params)),
      k_f_(params.k_f),
      u_min_(params.k_f * params.rotor_speed_min * params.rotor_speed_min),
      u_max_(params.k_f * params.rotor_speed_max * params.rotor_speed_max) {}

AllocationResult ControlAllocator::allocate(double thrust, const Eigen::Vector3d& torque_B) const {
  Vector4d u_rp = A_inv_.col(1) * torque_B.x() + A_inv_.col(2) * torque_B.y();
  const double span = u_max_ - u_min_;
  const double spread = u_rp.maxCoeff() - u_rp.minCoeff();
  if (spread > span) u_rp *= span / spread;
  Vector4d u = A_inv_.col(0) * thrust + u_rp;
  const double shift = std::min(std::max(0.0, u_min_ - u.minCoeff()), u_max_ - u.maxCoeff());
  u.array() += shift;
  const Vector4d u_y = A_inv_.col(3) * torque_B.z();
  double k = 1.0;  // the largest k in [0, 1] with u + k u_y inside [u_min, u_max]
  for (int i = 0; i < 4; ++i) {
    if (u_y[i] > 0) k = std::min(k, (u_max_ - u[i]) / u_y[i]);
    if (u_y[i] < 0) k = std::min(k, (u_min_ - u[i]) / u_y[i]);
  }
  k = std::max(k, 0.0);
  u = (u + k * u_y).cwiseMax(u_min_).cwiseMin(u_max_);
  AllocationResult r;
  r.achieved = A_ * u;
  const Vector4d demanded(thrust, torque_B.x(), torque_B.y(), torque_B.z());
  const double tol = 1e-9 * std::max(1.0, u_max_);
  for (int i = 0; i < 4; ++i) {
    const double d = demanded[i] - r.achieved[i];
    r.saturation[i] = std::abs(d) <= tol ? 0 : (d > 0 ? 1 : -1);
  }
  r.rotor_speeds = (u / k_f_).cwiseSqrt();
  return r;
}

}  // namespace cufund
