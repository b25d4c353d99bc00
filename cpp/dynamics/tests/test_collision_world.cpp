// CollisionWorld against analytic separations: boxes and spheres touching, penetrating and just
// missing floor and wall meshes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "collision_world.h"

namespace cufund {
namespace {

// A square of side 2*L in the plane x = x0 (normal -x, wall) or z = z0 (normal +z, floor).
void add_floor(CollisionWorld& w, double z0, double L = 10.0) {
  const std::vector<double> v = {-L, -L, z0, L, -L, z0, L, L, z0, -L, L, z0};
  const std::vector<std::uint32_t> t = {0, 1, 2, 0, 2, 3};
  w.add_mesh(v.data(), 4, t.data(), 2);
}

void add_wall(CollisionWorld& w, double x0, double L = 10.0) {
  const std::vector<double> v = {x0, -L, -L, x0, L, -L, x0, L, L, x0, -L, L};
  const std::vector<std::uint32_t> t = {0, 2, 1, 0, 3, 2};
  w.add_mesh(v.data(), 4, t.data(), 2);
}

const double kIdentity[4] = {1, 0, 0, 0};

TEST(CollisionWorld, BoxPenetratingTheFloorReportsDepthPointAndNormal) {
  CollisionWorld w;
  add_floor(w, 0.0);
  w.set_vehicle_box(0.1, 0.1, 0.05);
  const double p[3] = {0.3, -0.2, 0.04};  // bottom face at z = -0.01
  const Contact c = w.check(p, kIdentity);
  ASSERT_TRUE(c.hit);
  EXPECT_EQ(c.object_id, 0);
  EXPECT_NEAR(c.distance, -0.01, 1e-3);
  EXPECT_NEAR(c.normal_W[2], 1.0, 1e-6);
  EXPECT_NEAR(c.point_W[2], 0.0, 1e-3);
  EXPECT_NEAR(c.point_W[0], 0.3, 0.1 + 1e-3);
}

TEST(CollisionWorld, NearMissIsNoContactUnlessWithinTheMargin) {
  CollisionWorld w;
  add_floor(w, 0.0);
  w.set_vehicle_box(0.1, 0.1, 0.05);
  const double p[3] = {0.0, 0.0, 0.06};  // 1 cm above the floor
  EXPECT_FALSE(w.check(p, kIdentity).hit);
  const Contact c = w.check(p, kIdentity, 0.02);
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.distance, 0.01, 1e-3);
}

TEST(CollisionWorld, RotatedBoxReachesFartherAlongItsDiagonal) {
  CollisionWorld w;
  add_wall(w, 1.0);
  w.set_vehicle_box(0.1, 0.1, 0.05);
  const double s = std::sqrt(0.5);
  const double yaw45[4] = {std::cos(M_PI / 8), 0, 0, std::sin(M_PI / 8)};
  const double reach = 0.1 / s;  // half diagonal of the 0.2 m square
  const double miss[3] = {1.0 - reach - 0.005, 0, 0};
  const double hit[3] = {1.0 - reach + 0.005, 0, 0};
  EXPECT_FALSE(w.check(miss, yaw45).hit);
  const Contact c = w.check(hit, yaw45);
  ASSERT_TRUE(c.hit);
  EXPECT_NEAR(c.distance, -0.005, 1e-3);
  EXPECT_NEAR(c.normal_W[0], -1.0, 1e-6);  // from the wall towards the vehicle
  // Unrotated, the same position is clear of the wall.
  EXPECT_FALSE(w.check(hit, kIdentity).hit);
}

TEST(CollisionWorld, SphereTouchesTheNearestOfTwoObjects) {
  CollisionWorld w;
  add_floor(w, 0.0);
  add_wall(w, 2.0);
  w.set_vehicle_sphere(0.2);
  const double p[3] = {1.85, 0.0, 1.0};
  const Contact c = w.check(p, kIdentity);
  ASSERT_TRUE(c.hit);
  EXPECT_EQ(c.object_id, 1);
  EXPECT_NEAR(c.distance, -0.05, 1e-3);
  EXPECT_NEAR(c.point_W[0], 2.0, 1e-3);
  EXPECT_EQ(w.num_objects(), 2u);
  const double clear[3] = {1.5, 0.0, 1.0};
  EXPECT_FALSE(w.check(clear, kIdentity).hit);
}

}  // namespace
}  // namespace cufund
