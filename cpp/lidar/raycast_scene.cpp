#include "raycast_scene.h"

#include "ray_sort.h"
#include "thread_pool.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <mutex>
#include <shared_mutex>
#include <stdexcept>
#include <utility>
#include <vector>

namespace cufund::lidar {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// Rays per thread-pool work item: large enough to amortise scheduling, small enough to balance two
// threads when one half of a scan sees sky and the other walls.
constexpr std::size_t kChunk = kMaxTileRays;

// Scenes at least this large get coherent rays reordered into angular tiles (RayOrder::kAuto), and
// sorted rays keyed by where they cross the scene's box rather than by heading: their BVH outgrows
// the caches, and locality beats packet coherence.
constexpr std::size_t kTileMinTriangles = 50000;

// Incoherent batches of at least this many rays, on scenes of at least this many triangles, are
// sorted by heading (RayOrder::kAuto). Sorting, gathering and unsorting cost ~25 ns per ray on one
// core; on a 200-triangle UV sphere, rays from inside already save more than that, on a lone
// triangle (~35 ns per ray in all) they do not.
constexpr std::size_t kSortMinRays = 4096;
constexpr std::size_t kSortMinTriangles = 1000;

inline void write_miss(const RayHits& out, std::size_t i) {
  out.t_hit[i] = kInf;
  if (out.geometry_ids) out.geometry_ids[i] = kInvalidId;
  if (out.primitive_ids) out.primitive_ids[i] = kInvalidId;
  if (out.primitive_uvs) out.primitive_uvs[2 * i] = out.primitive_uvs[2 * i + 1] = 0.0f;
  if (out.normals) out.normals[3 * i] = out.normals[3 * i + 1] = out.normals[3 * i + 2] = 0.0f;
}

inline void write_hit(const RayHits& out, std::size_t i, float t, unsigned geom, unsigned prim, float u, float v,
                      float nx, float ny, float nz) {
  if (geom == RTC_INVALID_GEOMETRY_ID) {
    write_miss(out, i);
    return;
  }
  out.t_hit[i] = t;
  if (out.geometry_ids) out.geometry_ids[i] = geom;
  if (out.primitive_ids) out.primitive_ids[i] = prim;
  if (out.primitive_uvs) {
    out.primitive_uvs[2 * i] = u;
    out.primitive_uvs[2 * i + 1] = v;
  }
  if (out.normals) {
    // Embree's Ng is (v0-v1)x(v2-v0) = (v1-v0)x(v2-v0); normalise like Open3D.
    const float len = std::sqrt(nx * nx + ny * ny + nz * nz);
    const float s = len > 0.0f ? 1.0f / len : 0.0f;
    out.normals[3 * i] = nx * s;
    out.normals[3 * i + 1] = ny * s;
    out.normals[3 * i + 2] = nz * s;
  }
}

void cast_single(RTCScene scene, const float* rays, std::size_t begin, std::size_t end, const RayHits& out) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  for (std::size_t i = begin; i < end; ++i) {
    const float* r = rays + 6 * i;
    RTCRayHit rh;
    rh.ray.org_x = r[0];
    rh.ray.org_y = r[1];
    rh.ray.org_z = r[2];
    rh.ray.dir_x = r[3];
    rh.ray.dir_y = r[4];
    rh.ray.dir_z = r[5];
    rh.ray.tnear = 0.0f;
    rh.ray.tfar = kInf;
    rh.ray.time = 0.0f;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, &ctx, &rh);
    write_hit(out, i, rh.ray.tfar, rh.hit.geomID, rh.hit.primID, rh.hit.u, rh.hit.v, rh.hit.Ng_x, rh.hit.Ng_y,
              rh.hit.Ng_z);
  }
}

// Traces the rays at positions [begin, end) in 8-wide packets (ray index[j] at position j, or ray j
// itself when index is null) and calls emit(j, packet, lane) for each. `coherent` tells Embree the
// packets are coherent (rays from one origin), which picks a frustum traversal; its distances may
// differ from the single-ray path's in the last bits, so sorted batches leave it off and match
// single rays exactly.
template <typename Emit>
void trace_packets8(RTCScene scene, const float* rays, std::size_t begin, std::size_t end, const std::uint32_t* index,
                    bool coherent, const Emit& emit) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  if (coherent) ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  alignas(32) int valid[8];
  alignas(32) RTCRayHit8 rh;
  for (std::size_t b = begin; b < end; b += 8) {
    const int m = static_cast<int>(std::min<std::size_t>(8, end - b));
    for (int k = 0; k < 8; ++k) {
      const bool on = k < m;
      valid[k] = on ? -1 : 0;
      const std::size_t j = on ? b + k : b;
      const float* r = rays + 6 * (index ? index[j] : j);
      rh.ray.org_x[k] = r[0];
      rh.ray.org_y[k] = r[1];
      rh.ray.org_z[k] = r[2];
      rh.ray.dir_x[k] = r[3];
      rh.ray.dir_y[k] = r[4];
      rh.ray.dir_z[k] = r[5];
      rh.ray.tnear[k] = 0.0f;
      rh.ray.tfar[k] = kInf;
      rh.ray.time[k] = 0.0f;
      rh.ray.mask[k] = 0xFFFFFFFFu;
      rh.ray.id[k] = 0;
      rh.ray.flags[k] = 0;
      rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
    }
    rtcIntersect8(valid, scene, &ctx, &rh);
    for (int k = 0; k < m; ++k) emit(b + k, rh, k);
  }
}

void cast_packets8(RTCScene scene, const float* rays, std::size_t begin, std::size_t end, const RayHits& out,
                   const std::uint32_t* index = nullptr, bool coherent = true) {
  trace_packets8(scene, rays, begin, end, index, coherent, [&](std::size_t j, const RTCRayHit8& rh, int k) {
    write_hit(out, index ? index[j] : j, rh.ray.tfar[k], rh.hit.geomID[k], rh.hit.primID[k], rh.hit.u[k], rh.hit.v[k],
              rh.hit.Ng_x[k], rh.hit.Ng_y[k], rh.hit.Ng_z[k]);
  });
}

// One ray's raw hit, kept in sorted order until unsort_hits writes it where the caller wants it.
// Half a cache line: a random read touches one line, not two.
struct alignas(32) StagedHit {
  float t, u, v, ng[3];
  std::uint32_t geom, prim;
};

// Casts the sorted rays index[begin], ..., index[end - 1] (end - begin <= kChunk) in 8-wide packets
// into staged[begin, end), and notes where each ray went in position[ray]. The rays sit anywhere in
// memory: a tight loop gathers them first, so that the cache misses overlap instead of stalling the
// traversal one by one.
void cast_sorted(RTCScene scene, const float* rays, const std::uint32_t* index, std::size_t begin, std::size_t end,
                 StagedHit* staged, std::uint32_t* position) {
  const std::size_t m = end - begin;
  constexpr std::size_t kAhead = 16;
  float local[6 * kChunk];
  for (std::size_t k = 0; k < m; ++k) {
    if (k + kAhead < m) __builtin_prefetch(rays + 6 * std::size_t{index[begin + k + kAhead]});
    const std::uint32_t i = index[begin + k];
    std::copy_n(rays + 6 * std::size_t{i}, 6, local + 6 * k);
    position[i] = static_cast<std::uint32_t>(begin + k);
  }
  trace_packets8(scene, local, 0, m, nullptr, false, [&](std::size_t k, const RTCRayHit8& rh, int lane) {
    staged[begin + k] = {rh.ray.tfar[lane],   rh.hit.u[lane],
                         rh.hit.v[lane],      {rh.hit.Ng_x[lane], rh.hit.Ng_y[lane], rh.hit.Ng_z[lane]},
                         rh.hit.geomID[lane], rh.hit.primID[lane]};
  });
}

// Writes the staged hits of rays [begin, end) to their places in out (a gather: the random reads
// overlap far better than random writes to five arrays would).
void unsort_hits(const StagedHit* staged, const std::uint32_t* position, std::size_t begin, std::size_t end,
                 const RayHits& out) {
  constexpr std::size_t kAhead = 16;
  for (std::size_t i = begin; i < end; ++i) {
    if (i + kAhead < end) __builtin_prefetch(staged + position[i + kAhead]);
    const StagedHit& h = staged[position[i]];
    write_hit(out, i, h.t, h.geom, h.prim, h.u, h.v, h.ng[0], h.ng[1], h.ng[2]);
  }
}

// True when rays are mostly in runs sharing one origin (a sensor frame or an image), sampled cheaply.
bool looks_coherent(const float* rays, std::size_t n) {
  if (n < 64) return false;
  const std::size_t step = std::max<std::size_t>(1, n / 256);
  std::size_t same = 0, total = 0;
  for (std::size_t i = 0; i + 1 < n; i += step, ++total) {
    const float* a = rays + 6 * i;
    const float* b = a + 6;
    same += (a[0] == b[0] && a[1] == b[1] && a[2] == b[2]) ? 1 : 0;
  }
  return same * 2 > total;
}

// The first non-finite or zero-direction ray of a batch (kOk when there is none).
SceneResult check_rays(const float* rays, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    const float* r = rays + 6 * i;
    if (!(std::isfinite(r[0]) && std::isfinite(r[1]) && std::isfinite(r[2]) && std::isfinite(r[3]) &&
          std::isfinite(r[4]) && std::isfinite(r[5]))) {
      return {SceneStatus::kNonFiniteRay, i, kInvalidId};
    }
    if (r[3] == 0.0f && r[4] == 0.0f && r[5] == 0.0f) return {SceneStatus::kZeroDirection, i, kInvalidId};
  }
  return {};
}

// Any-hit query of rays [begin, end) in 8-wide packets: occluded[i] = 1 where ray i hits anything.
void occluded_packets8(RTCScene scene, const float* rays, std::size_t begin, std::size_t end, std::uint8_t* occluded) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;  // a hint only: the answers are the same either way
  alignas(32) int valid[8];
  alignas(32) RTCRay8 ray;
  for (std::size_t b = begin; b < end; b += 8) {
    const int m = static_cast<int>(std::min<std::size_t>(8, end - b));
    for (int k = 0; k < 8; ++k) {
      const bool on = k < m;
      valid[k] = on ? -1 : 0;
      const float* r = rays + 6 * (on ? b + k : b);
      ray.org_x[k] = r[0];
      ray.org_y[k] = r[1];
      ray.org_z[k] = r[2];
      ray.dir_x[k] = r[3];
      ray.dir_y[k] = r[4];
      ray.dir_z[k] = r[5];
      ray.tnear[k] = 0.0f;
      ray.tfar[k] = kInf;
      ray.time[k] = 0.0f;
      ray.mask[k] = 0xFFFFFFFFu;
      ray.id[k] = 0;
      ray.flags[k] = 0;
    }
    rtcOccluded8(valid, scene, &ctx, &ray);
    // Embree sets tfar to -inf on an occluded ray
    for (int k = 0; k < m; ++k) occluded[b + k] = ray.tfar[k] < 0.0f ? 1 : 0;
  }
}

}  // namespace

struct RaycastScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::size_t geometries = 0;
  std::size_t triangles = 0;
  mutable std::mutex commit_mutex;
  mutable bool dirty = true;
  // The scene's bounding box after the last commit (inverted while empty).
  mutable float lo[3] = {kInf, kInf, kInf}, hi[3] = {-kInf, -kInf, -kInf};
  // Embree forbids changing a scene while it is traversed: casts share this lock, additions own it.
  mutable std::shared_mutex scene_mutex;
  // The instanced base's Embree scene (retained), or null.
  RTCScene base_scene = nullptr;
  // Another scene instances this one: additions are refused (set under scene_mutex, read under it).
  std::atomic<bool> instanced{false};

  explicit Impl(RTCDevice shared = nullptr) {
    if (shared != nullptr) {
      rtcRetainDevice(shared);
      device = shared;
    } else {
      device = rtcNewDevice(nullptr);
    }
    if (!device)
      throw std::runtime_error("Embree: rtcNewDevice failed (error " +
                               std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))) + ")");
    scene = rtcNewScene(device);
    // A better BVH costs build time once and pays back on every ray of every frame.
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    // Watertight: a ray through a shared edge or vertex never slips between two triangles.
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
  }
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (base_scene) rtcReleaseScene(base_scene);
    if (device) rtcReleaseDevice(device);
  }
  void commit() const {
    std::lock_guard<std::mutex> lock(commit_mutex);
    if (dirty) {
      rtcCommitScene(scene);
      RTCBounds b;
      rtcGetSceneBounds(scene, &b);
      const bool empty = !(b.lower_x <= b.upper_x && b.lower_y <= b.upper_y && b.lower_z <= b.upper_z);
      const float l[3] = {b.lower_x, b.lower_y, b.lower_z}, h[3] = {b.upper_x, b.upper_y, b.upper_z};
      for (int k = 0; k < 3; ++k) {
        lo[k] = empty ? kInf : l[k];
        hi[k] = empty ? -kInf : h[k];
      }
      dirty = false;
    }
  }
};

RaycastScene::RaycastScene() : impl_(std::make_unique<Impl>()) {}

RaycastScene::RaycastScene(Instancing, const RaycastScene& base) : impl_(std::make_unique<Impl>(base.impl_->device)) {
  std::size_t n = 0, triangles = 0;
  {
    // base's counts, its freeze and its commit under one lock: no addition slips in between (its id would be taken)
    std::shared_lock<std::shared_mutex> no_additions(base.impl_->scene_mutex);
    n = base.impl_->geometries;
    triangles = base.impl_->triangles;
    if (n == 0) return;
    base.impl_->instanced = true;
    base.impl_->commit();
  }
  rtcRetainScene(base.impl_->scene);
  impl_->base_scene = base.impl_->scene;
  RTCGeometry g = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_INSTANCE);
  rtcSetGeometryInstancedScene(g, base.impl_->scene);
  const float identity[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};  // 3x4 column-major: no rotation, no offset
  rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, identity);
  rtcCommitGeometry(g);
  // A hit inside the instance reports base's own geometry id (the instance's id goes to instID, which nothing reads),
  // so the instance takes id 0 (ids below n are otherwise unused here) and added meshes n, n + 1, ...
  rtcAttachGeometryByID(impl_->scene, g, 0);
  rtcReleaseGeometry(g);
  impl_->geometries = n;
  impl_->triangles = triangles;
}
RaycastScene::~RaycastScene() = default;
RaycastScene::RaycastScene(RaycastScene&&) noexcept = default;
RaycastScene& RaycastScene::operator=(RaycastScene&&) noexcept = default;

SceneResult RaycastScene::add_triangles(const float* vertices, std::size_t nv, const std::uint32_t* triangles,
                                        std::size_t nt) {
  if (nt == 0) return {SceneStatus::kNoTriangles, 0, kInvalidId};
  for (std::size_t i = 0; i < 3 * nv; ++i) {
    if (!std::isfinite(vertices[i])) return {SceneStatus::kNonFiniteVertex, i / 3, kInvalidId};
  }
  for (std::size_t i = 0; i < 3 * nt; ++i) {
    if (triangles[i] >= nv) return {SceneStatus::kIndexOutOfRange, i / 3, kInvalidId};
  }
  RTCGeometry g = rtcNewGeometry(impl_->device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), nv));
  auto* ib = static_cast<std::uint32_t*>(
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(std::uint32_t), nt));
  std::copy(vertices, vertices + 3 * nv, vb);
  std::copy(triangles, triangles + 3 * nt, ib);
  rtcCommitGeometry(g);
  ForkSafeSection no_fork;  // a child must not inherit the scene's locks held
  std::unique_lock<std::shared_mutex> no_casts(impl_->scene_mutex);
  if (impl_->instanced) {
    rtcReleaseGeometry(g);
    return {SceneStatus::kInstanced, 0, kInvalidId};
  }
  // ids 0, 1, 2, ... in order (after an instanced base's: see the constructor)
  const auto id = static_cast<unsigned>(impl_->geometries);
  rtcAttachGeometryByID(impl_->scene, g, id);
  rtcReleaseGeometry(g);
  std::lock_guard<std::mutex> lock(impl_->commit_mutex);
  impl_->dirty = true;
  impl_->geometries += 1;
  impl_->triangles += nt;
  return {SceneStatus::kOk, 0, id};
}

SceneResult RaycastScene::cast_rays(const float* rays, std::size_t n, const RayHits& out, int nthreads,
                                    RayOrder order) const {
  if (const SceneResult bad = check_rays(rays, n); bad.status != SceneStatus::kOk) return bad;
  ForkSafeSection no_fork;  // a child must not inherit the scene's locks held
  std::shared_lock<std::shared_mutex> no_additions(impl_->scene_mutex);
  impl_->commit();
  const bool coherent = order == RayOrder::kCoherent || (order == RayOrder::kAuto && looks_coherent(rays, n));
  RTCScene scene = impl_->scene;
  // Tiling pays where the BVH outgrows the caches; on small scenes it costs more than it saves.
  const bool tiles = coherent && order == RayOrder::kAuto && impl_->triangles >= kTileMinTriangles;
  const bool sorted = n <= std::numeric_limits<std::uint32_t>::max() &&
                      (order == RayOrder::kSorted || (order == RayOrder::kAuto && !coherent && n >= kSortMinRays &&
                                                      impl_->triangles >= kSortMinTriangles));
  // Kept for the calling thread's next sorted cast (40 bytes per ray, 16 more in spatial_order):
  // fresh pages would cost about as much as the sort.
  thread_local std::vector<std::uint32_t> index, position;
  thread_local std::vector<StagedHit> staged;
  if (sorted) {
    if (index.size() < n) {
      index.resize(n);
      position.resize(n);
      staged.resize(n);
    }
    // Keys measured on a UV sphere, random rays from inside: heading 8% faster at 10k triangles,
    // box crossing 8% faster at 1M (and 2-10% at 100k).
    const RayKey key = impl_->triangles >= kTileMinTriangles ? RayKey::kBoxCrossing : RayKey::kHeading;
    spatial_order(rays, n, impl_->lo, impl_->hi, key, index.data(), nthreads);
  }
  // The thread_local names mean other vectors on a pool thread: pass pointers.
  const std::uint32_t* sorted_index = index.data();
  std::uint32_t* sorted_position = position.data();
  StagedHit* staged_hits = staged.data();
  const auto rays_n = static_cast<std::ptrdiff_t>(n);  // parallel_chunks counts in ptrdiff_t
  parallel_chunks(rays_n, kChunk, nthreads, [&](std::size_t begin, std::size_t end, std::size_t) {
    if (sorted) {
      cast_sorted(scene, rays, sorted_index, begin, end, staged_hits, sorted_position);
    } else if (tiles) {
      std::uint16_t local[kChunk];
      std::uint32_t tile[kChunk];
      direction_tile_order(rays, begin, end, local);
      for (std::size_t k = 0; k < end - begin; ++k) tile[k] = static_cast<std::uint32_t>(begin + local[k]);
      cast_packets8(scene, rays, 0, end - begin, out, tile);
    } else if (coherent) {
      cast_packets8(scene, rays, begin, end, out);
    } else {
      cast_single(scene, rays, begin, end, out);
    }
  });
  if (sorted) {
    parallel_chunks(rays_n, kChunk, nthreads, [&](std::size_t begin, std::size_t end, std::size_t) {
      unsort_hits(staged_hits, sorted_position, begin, end, out);
    });
  }
  return {};
}

void RaycastScene::cast_rays_ordered(const float* rays, std::size_t n, const std::uint32_t* order, const RayHits& out,
                                     int nthreads) const {
  ForkSafeSection no_fork;  // a child must not inherit the scene's locks held
  std::shared_lock<std::shared_mutex> no_additions(impl_->scene_mutex);
  impl_->commit();
  RTCScene scene = impl_->scene;
  parallel_chunks(static_cast<std::ptrdiff_t>(n), kChunk, nthreads,
                  [&](std::size_t begin, std::size_t end, std::size_t) {
                    cast_packets8(scene, rays, begin, end, out, order, true);
                  });
}

SceneResult RaycastScene::occluded(const float* rays, std::size_t n, std::uint8_t* occluded, int nthreads) const {
  if (const SceneResult bad = check_rays(rays, n); bad.status != SceneStatus::kOk) return bad;
  ForkSafeSection no_fork;  // a child must not inherit the scene's locks held
  std::shared_lock<std::shared_mutex> no_additions(impl_->scene_mutex);
  impl_->commit();
  RTCScene scene = impl_->scene;
  parallel_chunks(
      static_cast<std::ptrdiff_t>(n), kChunk, nthreads,
      [&](std::size_t begin, std::size_t end, std::size_t) { occluded_packets8(scene, rays, begin, end, occluded); });
  return {};
}

std::size_t RaycastScene::num_geometries() const { return impl_->geometries; }
std::size_t RaycastScene::num_triangles() const { return impl_->triangles; }

}  // namespace cufund::lidar
