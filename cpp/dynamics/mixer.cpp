#include "mixer.h"

#include <Eigen/LU>

namespace cufund {

Matrix4d allocation_matrix(const QuadrotorParams& params) {
  const RotorGeometry g = rotor_geometry(params);
  Matrix4d a;
  for (int i = 0; i < kNumRotors; ++i) {
    a(0, i) = 1.0;
    a(1, i) = g.position_B[i].y();
    a(2, i) = -g.position_B[i].x();
    a(3, i) = -g.spin[i] * params.c_m;
  }
  return a;
}

Matrix4d allocation_matrix_inverse(const QuadrotorParams& params) { return allocation_matrix(params).inverse(); }

}  // namespace cufund
