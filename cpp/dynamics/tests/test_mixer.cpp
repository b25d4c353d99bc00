#include <gtest/gtest.h>

#include <Eigen/LU>

#include "mixer.h"
#include "test_helpers.h"

namespace cufund {
namespace {

class MixerTest : public ::testing::TestWithParam<RotorLayout> {};

TEST_P(MixerTest, InverseComposesToIdentity) {
  QuadrotorParams p = testing::small_quad();
  p.layout = GetParam();
  const Matrix4d a = allocation_matrix(p);
  const Matrix4d a_inv = allocation_matrix_inverse(p);
  EXPECT_LT((a * a_inv - Matrix4d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LT((a_inv * a - Matrix4d::Identity()).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Mixer, PlusLayoutIsPaperEquationOneInFlu) {
  QuadrotorParams p = testing::small_quad();
  p.layout = RotorLayout::kPlus;
  const double d = p.arm_length, c = p.c_m;
  Matrix4d paper_frd;  // paper eq. (1), PX4 FRD body frame
  paper_frd << 1, 1, 1, 1, 0, -d, 0, d, d, 0, -d, 0, -c, c, -c, c;
  // FRD -> FLU flips the y and z axes: M_y and M_z change sign.
  const Eigen::Vector4d flip(1, 1, -1, -1);
  const Matrix4d expected = flip.asDiagonal() * paper_frd;
  EXPECT_LT((allocation_matrix(p) - expected).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(Mixer, XLayoutMomentSigns) {
  // Front-right rotor alone (PX4 motor 1, counter-clockwise): thrust at -y gives a negative roll moment
  // (M_x = y f), at +x a negative pitch moment (M_y = -x f), and its spin a clockwise reaction torque (-M_z).
  const Matrix4d a = allocation_matrix(testing::small_quad());
  EXPECT_LT(a(1, 0), 0);
  EXPECT_LT(a(2, 0), 0);
  EXPECT_LT(a(3, 0), 0);
  // Front-left (motor 3, clockwise): positive roll, negative pitch, positive yaw.
  EXPECT_GT(a(1, 2), 0);
  EXPECT_LT(a(2, 2), 0);
  EXPECT_GT(a(3, 2), 0);
}

INSTANTIATE_TEST_SUITE_P(Layouts, MixerTest, ::testing::Values(RotorLayout::kPlus, RotorLayout::kX));

}  // namespace
}  // namespace cufund
