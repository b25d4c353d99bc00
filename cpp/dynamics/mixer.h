// Control allocation of the paper's eq. (1): rotor thrusts <-> collective thrust and body moments.
//
// The paper writes eq. (1) for a "+" quadrotor in PX4's FRD body frame. cufund works in FLU, where
//   f   = sum f_i
//   M_x =  sum y_i f_i                 (roll)
//   M_y = -sum x_i f_i                 (pitch)
//   M_z = -sum s_i c_M f_i             (yaw; s_i = +1 for a counter-clockwise rotor)
// so for the "+" layout the M_x row equals the paper's and the M_y, M_z rows change sign (y and z
// axes flip between FRD and FLU).
#pragma once

#include <Eigen/Core>

#include "quadrotor_params.h"

namespace cufund {

using Matrix4d = Eigen::Matrix<double, 4, 4>;
using Vector4d = Eigen::Matrix<double, 4, 1>;

// A maps rotor thrusts [f_1..f_4] [N] to [f, M_x, M_y, M_z] [N, N m, N m, N m] in body FLU.
Matrix4d allocation_matrix(const QuadrotorParams& params);
// A^-1: wrench [f, M_x, M_y, M_z] to rotor thrusts (may be negative or beyond limits: no saturation).
Matrix4d allocation_matrix_inverse(const QuadrotorParams& params);

}  // namespace cufund
