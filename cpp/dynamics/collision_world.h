// Collision checking of a vehicle's shape against static world meshes, with Bullet (hidden behind a
// pimpl: this header includes nothing from Bullet).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

namespace cufund {

// The deepest contact of a query; hit == false when the shapes are farther apart than the margin.
struct Contact {
  bool hit = false;
  int object_id = -1;              // id returned by add_mesh
  double point_W[3] = {0, 0, 0};   // contact point on the world mesh [m]
  double normal_W[3] = {0, 0, 0};  // unit normal at the contact, pointing from the mesh to the vehicle
  double distance = 0.0;           // signed gap [m]: negative = penetration depth
};

class CollisionWorld {
 public:
  CollisionWorld();
  ~CollisionWorld();
  CollisionWorld(const CollisionWorld&) = delete;
  CollisionWorld& operator=(const CollisionWorld&) = delete;

  // Adds a static triangle mesh (vertices xyz row-major [m], triangles as vertex index triples; the
  // caller has checked that indices are in range and values finite). Returns its object id.
  int add_mesh(const double* vertices, std::size_t nv, const std::uint32_t* triangles, std::size_t nt);

  // The vehicle is a box of half extents (hx, hy, hz) [m] in the body frame, or a sphere of radius r.
  void set_vehicle_box(double hx, double hy, double hz);
  void set_vehicle_sphere(double radius);

  // Contact of the vehicle at body pose (p_W, q_WB [w, x, y, z]) with the world: the deepest contact
  // whose signed distance is <= margin [m], if any.
  Contact check(const double p_W[3], const double q_WB[4], double margin = 0.0) const;

  std::size_t num_objects() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cufund
