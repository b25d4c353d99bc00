#include "collision_world.h"

#include <btBulletCollisionCommon.h>

#include <algorithm>
#include <limits>
#include <vector>

namespace cufund {

struct CollisionWorld::Impl {
  btDefaultCollisionConfiguration config;
  btCollisionDispatcher dispatcher{&config};
  btDbvtBroadphase broadphase;
  btCollisionWorld world{&dispatcher, &broadphase, &config};
  std::vector<std::unique_ptr<btTriangleMesh>> meshes;
  std::vector<std::unique_ptr<btBvhTriangleMeshShape>> shapes;
  std::vector<std::unique_ptr<btCollisionObject>> objects;
  std::unique_ptr<btConvexShape> vehicle_shape;
  mutable btCollisionObject vehicle;

  ~Impl() {
    for (auto& o : objects) world.removeCollisionObject(o.get());
  }
};

namespace {

// Collects the deepest contact between the vehicle and any world object.
struct DeepestContact : btCollisionWorld::ContactResultCallback {
  const btCollisionObject* vehicle;
  double margin;
  Contact best;
  DeepestContact(const btCollisionObject* v, double m) : vehicle(v), margin(m) {}

  btScalar addSingleResult(btManifoldPoint& cp, const btCollisionObjectWrapper* a, int, int,
                           const btCollisionObjectWrapper* b, int, int) override {
    const double d = cp.getDistance();
    if (d > margin || (best.hit && d >= best.distance)) return 0;
    // Bullet's normal on B points from B to A; make it point from the world mesh to the vehicle.
    const bool vehicle_is_a = a->getCollisionObject() == vehicle;
    const btCollisionObject* other = vehicle_is_a ? b->getCollisionObject() : a->getCollisionObject();
    btVector3 n = cp.m_normalWorldOnB;
    btVector3 p = vehicle_is_a ? cp.getPositionWorldOnB() : cp.getPositionWorldOnA();
    if (!vehicle_is_a) n = -n;
    best.hit = true;
    best.object_id = other->getUserIndex();
    best.distance = d;
    for (int k = 0; k < 3; ++k) {
      best.point_W[k] = p[k];
      best.normal_W[k] = n[k];
    }
    return 0;
  }
};

}  // namespace

CollisionWorld::CollisionWorld() : impl_(std::make_unique<Impl>()) {
  impl_->vehicle_shape = std::make_unique<btSphereShape>(0.1);
  impl_->vehicle.setCollisionShape(impl_->vehicle_shape.get());
}

CollisionWorld::~CollisionWorld() = default;

int CollisionWorld::add_mesh(const double* vertices, std::size_t, const std::uint32_t* triangles, std::size_t nt) {
  auto mesh = std::make_unique<btTriangleMesh>(true, false);
  for (std::size_t t = 0; t < nt; ++t) {
    btVector3 v[3];
    for (int k = 0; k < 3; ++k) {
      const double* p = vertices + 3 * triangles[3 * t + k];
      v[k] = btVector3(static_cast<btScalar>(p[0]), static_cast<btScalar>(p[1]), static_cast<btScalar>(p[2]));
    }
    mesh->addTriangle(v[0], v[1], v[2], false);
  }
  auto shape = std::make_unique<btBvhTriangleMeshShape>(mesh.get(), true, true);
  shape->setMargin(0.0);
  auto object = std::make_unique<btCollisionObject>();
  object->setCollisionShape(shape.get());
  const int id = static_cast<int>(impl_->objects.size());
  object->setUserIndex(id);
  impl_->world.addCollisionObject(object.get());
  impl_->meshes.push_back(std::move(mesh));
  impl_->shapes.push_back(std::move(shape));
  impl_->objects.push_back(std::move(object));
  return id;
}

void CollisionWorld::set_vehicle_box(double hx, double hy, double hz) {
  // btBoxShape keeps its margin inside the half extents but rounds the corners with it: a 1 mm
  // margin keeps the corners sharp to 1 mm (Bullet's default 4 cm would not).
  auto box = std::make_unique<btBoxShape>(
      btVector3(static_cast<btScalar>(hx), static_cast<btScalar>(hy), static_cast<btScalar>(hz)));
  box->setMargin(static_cast<btScalar>(std::min({1e-3, hx, hy, hz})));
  impl_->vehicle_shape = std::move(box);
  impl_->vehicle.setCollisionShape(impl_->vehicle_shape.get());
}

void CollisionWorld::set_vehicle_sphere(double radius) {
  impl_->vehicle_shape = std::make_unique<btSphereShape>(static_cast<btScalar>(radius));
  impl_->vehicle.setCollisionShape(impl_->vehicle_shape.get());
}

Contact CollisionWorld::check(const double p_W[3], const double q_WB[4], double margin) const {
  btTransform T;
  T.setOrigin(btVector3(static_cast<btScalar>(p_W[0]), static_cast<btScalar>(p_W[1]), static_cast<btScalar>(p_W[2])));
  T.setRotation(btQuaternion(static_cast<btScalar>(q_WB[1]), static_cast<btScalar>(q_WB[2]),
                             static_cast<btScalar>(q_WB[3]), static_cast<btScalar>(q_WB[0])));
  impl_->vehicle.setWorldTransform(T);
  // Candidates: objects whose bounds overlap the vehicle's grown by the margin (contactTest's own
  // broadphase would miss a gap), then the narrow phase per pair.
  btVector3 lo, hi;
  impl_->vehicle_shape->getAabb(T, lo, hi);
  const btVector3 grow(static_cast<btScalar>(std::max(margin, 0.0)), static_cast<btScalar>(std::max(margin, 0.0)),
                       static_cast<btScalar>(std::max(margin, 0.0)));
  struct Candidates : btBroadphaseAabbCallback {
    std::vector<btCollisionObject*> objects;
    bool process(const btBroadphaseProxy* proxy) override {
      objects.push_back(static_cast<btCollisionObject*>(proxy->m_clientObject));
      return true;
    }
  } candidates;
  impl_->world.getBroadphase()->aabbTest(lo - grow, hi + grow, candidates);
  DeepestContact cb(&impl_->vehicle, margin);
  cb.m_closestDistanceThreshold = static_cast<btScalar>(std::max(margin, 0.0));
  for (btCollisionObject* o : candidates.objects) impl_->world.contactPairTest(&impl_->vehicle, o, cb);
  return cb.best;
}

std::size_t CollisionWorld::num_objects() const { return impl_->objects.size(); }

}  // namespace cufund
