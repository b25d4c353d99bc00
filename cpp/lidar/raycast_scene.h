// A scene of triangle meshes and a multithreaded ray caster over it, shaped like Open3D's
// RaycastingScene. Embree 3 is hidden behind a pimpl: this header includes nothing from it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

namespace cufund::lidar {

// geometry_ids / primitive_ids of a ray that hit nothing (Open3D's RaycastingScene.INVALID_ID).
inline constexpr std::uint32_t kInvalidId = 0xFFFFFFFFu;

enum class SceneStatus {
  kOk,
  kNoTriangles,      // a mesh with zero triangles
  kNonFiniteVertex,  // index: the vertex
  kIndexOutOfRange,  // index: the triangle
  kNonFiniteRay,     // index: the ray (origin or direction not finite)
  kZeroDirection,    // index: the ray (direction of zero length)
  kInstanced,        // add_triangles on a scene another scene instances (it can no longer change)
};

struct SceneResult {
  SceneStatus status = SceneStatus::kOk;
  std::size_t index = 0;          // offending element, when status != kOk
  std::uint32_t id = kInvalidId;  // geometry id from add_triangles
};

// Where cast_rays writes, one element (or row) per ray; any pointer but t_hit may be null to skip it.
struct RayHits {
  float* t_hit = nullptr;                  // (N,) distance in units of |direction|; +inf on a miss
  std::uint32_t* geometry_ids = nullptr;   // (N,) kInvalidId on a miss
  std::uint32_t* primitive_ids = nullptr;  // (N,) triangle index within its geometry; kInvalidId on a miss
  float* primitive_uvs = nullptr;          // (N, 2) barycentric (u, v) of the hit; 0 on a miss
  float* normals = nullptr;                // (N, 3) unit geometric normal, (v1-v0)x(v2-v0) side; 0 on a miss
};

// How cast_rays groups rays for traversal. The hit (or miss), ids, distance and normal of every ray
// are the same under each order up to the last bits of t_hit under kCoherent packets, which Embree
// traverses as frusta; kSorted and kIncoherent agree exactly.
enum class RayOrder {
  kAuto,        // packets when consecutive rays share an origin (regrouped into angular tiles of
                //   8 on scenes of >= 50k triangles); otherwise kSorted for batches of >= 4096
                //   rays on scenes of >= 1000 triangles, single rays for the rest
  kIncoherent,  // single-ray traversal in the given order
  kCoherent,    // 8-wide packets of consecutive rays (sensor scans, image rows)
  kSorted,      // rays sorted by where they cross the scene's box (ray_sort.h), then 8-wide packets
                //   in that order: random rays share BVH nodes and cache lines with their
                //   neighbours. The calling thread keeps 56 bytes per ray of scratch for its next
                //   call. At most 2^32 - 1 rays (larger batches are cast as kIncoherent).
};

class RaycastScene {
 public:
  RaycastScene();
  // A scene that starts with `base`'s geometries as one Embree instance (identity transform, sharing base's device
  // and acceleration structure instead of copying its triangles): a hit on base's geometry g reports geometry id g,
  // and geometries added here take the ids base.num_geometries(), base.num_geometries() + 1, ... as if base's meshes
  // had been added first. Made and cast again cheaply whatever base's size (a fleet's view of the other vehicles in
  // a large world). base is committed here and can no longer change (its add_triangles returns kInstanced: Embree
  // must not rebuild a scene another one traverses); base must outlive this scene. The hits
  // equal those of the copied meshes (the identity transform is exact), though Embree does not promise the last bits
  // of every distance across the two structures.
  struct Instancing {};
  RaycastScene(Instancing, const RaycastScene& base);
  ~RaycastScene();
  RaycastScene(const RaycastScene&) = delete;
  RaycastScene& operator=(const RaycastScene&) = delete;
  RaycastScene(RaycastScene&&) noexcept;
  RaycastScene& operator=(RaycastScene&&) noexcept;

  // Copies a mesh of nv vertices (xyz, row-major) and nt triangles (3 vertex indices each) into the
  // scene. Degenerate (zero-area) triangles are kept but can never be hit (Embree skips them).
  SceneResult add_triangles(const float* vertices, std::size_t nv, const std::uint32_t* triangles, std::size_t nt);

  // Casts n rays (ox, oy, oz, dx, dy, dz per row) in [0, +inf) along their direction.
  // nthreads <= 0 uses every core. Rays are checked first: a non-finite or zero-direction ray
  // returns its status and index and nothing is written.
  SceneResult cast_rays(const float* rays, std::size_t n, const RayHits& out, int nthreads = 0,
                        RayOrder order = RayOrder::kAuto) const;

  // Casts the n rays in the given `order` (a permutation of [0, n), e.g. a scan's rays channel by
  // channel so that neighbours in the order are neighbours in angle) in 8-wide coherent packets (about 3x
  // faster than single rays on a Mid-360 scan), writing each ray's hit at its own index. As with
  // kCoherent, distances may differ from single rays' in the last bits (Embree does not promise equality;
  // on the tunnel flight's 5.5 million LiDAR rays they were all equal). Rays must be finite with non-zero
  // directions (unchecked: the caller made them). nthreads <= 0 uses every core.
  void cast_rays_ordered(const float* rays, std::size_t n, const std::uint32_t* order, const RayHits& out,
                         int nthreads = 0) const;

  // Whether each of the n rays (as cast_rays takes them) hits anything in [0, +inf): occluded[i] = 1 or 0.
  // An any-hit query (Embree's rtcOccluded, 8-wide packets of consecutive rays, marked coherent): it stops
  // at the first triangle found, where cast_rays looks for the closest (shadow rays need no more). Rays are
  // checked as by cast_rays: a non-finite or zero-direction ray returns its status and index, nothing written.
  SceneResult occluded(const float* rays, std::size_t n, std::uint8_t* occluded, int nthreads = 0) const;

  std::size_t num_geometries() const;
  std::size_t num_triangles() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cufund::lidar
