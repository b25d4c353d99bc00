#include <gtest/gtest.h>

#include <cmath>

#include "rotation.h"

namespace cufund {
namespace {

// Rodrigues' formula R = I + sin(a) K + (1 - cos(a)) K^2 for a unit axis u (K its cross-product matrix).
void rodrigues(const double u[3], double a, double R[9]) {
  const double K[9] = {0, -u[2], u[1], u[2], 0, -u[0], -u[1], u[0], 0};
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      double K2 = 0;
      for (int k = 0; k < 3; ++k) K2 += K[3 * i + k] * K[3 * k + j];
      R[3 * i + j] = (i == j ? 1.0 : 0.0) + std::sin(a) * K[3 * i + j] + (1 - std::cos(a)) * K2;
    }
  }
}

TEST(QuatToRotation, IdentityQuaternionIsTheIdentity) {
  const double q[4] = {1, 0, 0, 0};
  double R[9];
  quat_to_rotation(q, R);
  for (int i = 0; i < 9; ++i) EXPECT_EQ(R[i], i % 4 == 0 ? 1.0 : 0.0) << i;
}

TEST(QuatToRotation, YawOfNinetyDegreesTakesXToY) {
  // [w, x, y, z] = [cos(a/2), 0, 0, sin(a/2)]: a yaw of a about +z, so R e_x = (cos a, sin a, 0).
  const double a = std::acos(-1.0) / 2;
  const double q[4] = {std::cos(a / 2), 0, 0, std::sin(a / 2)};
  double R[9];
  quat_to_rotation(q, R);
  const double expected[9] = {0, -1, 0, 1, 0, 0, 0, 0, 1};
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(R[i], expected[i], 1e-15) << i;
}

TEST(QuatToRotation, MatchesRodriguesForAnAxisAngle) {
  const double axes[3][3] = {{1, 0, 0}, {0, 0.6, -0.8}, {2, -3, 6}};  // the last one has norm 7
  for (const auto& axis : axes) {
    const double norm = std::sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
    const double u[3] = {axis[0] / norm, axis[1] / norm, axis[2] / norm};
    for (double a : {-2.5, -0.3, 0.7, 1.9, 3.1}) {
      const double s = std::sin(a / 2);
      const double q[4] = {std::cos(a / 2), s * u[0], s * u[1], s * u[2]};
      double R[9], expected[9];
      quat_to_rotation(q, R);
      rodrigues(u, a, expected);
      for (int i = 0; i < 9; ++i) EXPECT_NEAR(R[i], expected[i], 1e-14) << "angle " << a << ", entry " << i;
    }
  }
}

TEST(QuatToRotation, NormalisesItsInputAndIgnoresTheSign) {
  const double q[4] = {0.5, -0.1, 0.7, 0.3};
  const double n = std::sqrt(0.25 + 0.01 + 0.49 + 0.09);
  const double unit[4] = {q[0] / n, q[1] / n, q[2] / n, q[3] / n};
  const double scaled[4] = {-4 * q[0], -4 * q[1], -4 * q[2], -4 * q[3]};
  double R_unit[9], R_scaled[9];
  quat_to_rotation(unit, R_unit);
  quat_to_rotation(scaled, R_scaled);
  for (int i = 0; i < 9; ++i) EXPECT_NEAR(R_scaled[i], R_unit[i], 1e-15) << i;
  // A rotation: R R^T = I.
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      double d = 0;
      for (int k = 0; k < 3; ++k) d += R_scaled[3 * i + k] * R_scaled[3 * j + k];
      EXPECT_NEAR(d, i == j ? 1.0 : 0.0, 1e-15) << i << ", " << j;
    }
  }
}

}  // namespace
}  // namespace cufund
