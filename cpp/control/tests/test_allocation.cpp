#include <gtest/gtest.h>

#include "allocation.h"

namespace cufund {
namespace {

QuadrotorParams vehicle() {  // cufund.presets.cu_astro()
  QuadrotorParams p;
  p.mass = 0.8;
  p.inertia = Eigen::Vector3d(0.0037118, 0.0037118, 0.0062208).asDiagonal();
  p.arm_length = 0.07 * std::sqrt(2.0);
  p.k_f = 4.97e-7;
  p.c_m = 0.0125;
  p.tau_m = 0.03;
  p.rotor_speed_max = 3140.0;
  return p;
}

TEST(ControlAllocator, ExactInsideTheLimits) {
  const QuadrotorParams p = vehicle();
  const ControlAllocator alloc(p);
  const AllocationResult r = alloc.allocate(8.0, Eigen::Vector3d(0.05, -0.03, 0.01));
  EXPECT_NEAR(r.achieved[0], 8.0, 1e-12);
  EXPECT_NEAR(r.achieved[1], 0.05, 1e-12);
  EXPECT_NEAR(r.achieved[2], -0.03, 1e-12);
  EXPECT_NEAR(r.achieved[3], 0.01, 1e-12);
  for (int s : r.saturation) EXPECT_EQ(s, 0);
  // rotor speeds reproduce the achieved wrench through the allocation matrix
  const Vector4d u = p.k_f * r.rotor_speeds.cwiseAbs2();
  EXPECT_LT((allocation_matrix(p) * u - r.achieved).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(ControlAllocator, YawGivesWayToRollPitch) {
  const ControlAllocator alloc(vehicle());
  const AllocationResult r = alloc.allocate(7.85, Eigen::Vector3d(0.3, 0.0, 0.5));
  EXPECT_NEAR(r.achieved[1], 0.3, 1e-9);
  EXPECT_GT(r.achieved[3], 0.0);
  EXPECT_LT(r.achieved[3], 0.5);
  EXPECT_EQ(r.saturation[3], 1);
  EXPECT_EQ(r.saturation[1], 0);
}

TEST(ControlAllocator, CollectiveGivesWayToRollPitchAtFullThrust) {
  const ControlAllocator alloc(vehicle());
  const AllocationResult r = alloc.allocate(alloc.max_thrust(), Eigen::Vector3d(0.2, -0.1, 0.0));
  EXPECT_NEAR(r.achieved[1], 0.2, 1e-9);
  EXPECT_NEAR(r.achieved[2], -0.1, 1e-9);
  EXPECT_LT(r.achieved[0], alloc.max_thrust());
  EXPECT_EQ(r.saturation[0], 1);
  EXPECT_LE(r.rotor_speeds.maxCoeff(), 3140.0 + 1e-9);
  EXPECT_GE(r.rotor_speeds.minCoeff(), 0.0);
}

TEST(ControlAllocator, RollPitchScaledWhenBeyondRange) {
  const ControlAllocator alloc(vehicle());
  const AllocationResult r = alloc.allocate(7.85, Eigen::Vector3d(5.0, 5.0, 0.0));
  // direction kept, magnitude reduced
  EXPECT_NEAR(r.achieved[1], r.achieved[2], 1e-9);
  EXPECT_LT(r.achieved[1], 5.0);
  EXPECT_EQ(r.saturation[1], 1);
}

}  // namespace
}  // namespace cufund
