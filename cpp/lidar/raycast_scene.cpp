#include "raycast_scene.h"

#include "thread_pool.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>
#include <shared_mutex>
#include <stdexcept>
#include <utility>

namespace cufund::lidar {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// Rays per thread-pool work item: large enough to amortise scheduling, small enough to balance two
// threads when one half of a scan sees sky and the other walls.
constexpr std::size_t kChunk = 1024;

// Scenes at least this large get coherent rays reordered into angular tiles (RayOrder::kAuto).
constexpr std::size_t kTileMinTriangles = 50000;

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

// Casts rays [begin, end) in 8-wide packets of consecutive rays, or, when `order` is given, of rays
// begin + order[0], begin + order[1], ... (a permutation of [0, end - begin)).
void cast_packets8(RTCScene scene, const float* rays, std::size_t begin, std::size_t end, const RayHits& out,
                   const std::uint16_t* order = nullptr) {
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  alignas(32) int valid[8];
  alignas(32) RTCRayHit8 rh;
  for (std::size_t b = begin; b < end; b += 8) {
    const int m = static_cast<int>(std::min<std::size_t>(8, end - b));
    for (int k = 0; k < 8; ++k) {
      const bool on = k < m;
      valid[k] = on ? -1 : 0;
      const std::size_t j = b + (on ? k : 0);
      const float* r = rays + 6 * (order ? begin + order[j - begin] : j);
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
    for (int k = 0; k < m; ++k) {
      write_hit(out, order ? begin + order[b + k - begin] : b + k, rh.ray.tfar[k], rh.hit.geomID[k], rh.hit.primID[k], rh.hit.u[k], rh.hit.v[k],
                rh.hit.Ng_x[k], rh.hit.Ng_y[k], rh.hit.Ng_z[k]);
    }
  }
}

// Spreads the low 16 bits of v to the even bits.
inline std::uint32_t spread16(std::uint32_t v) {
  v &= 0x0000FFFFu;
  v = (v | (v << 8)) & 0x00FF00FFu;
  v = (v | (v << 4)) & 0x0F0F0F0Fu;
  v = (v | (v << 2)) & 0x33333333u;
  v = (v | (v << 1)) & 0x55555555u;
  return v;
}

// Orders the rays of one chunk (at most kChunk) along a Morton curve over their directions
// (octahedral map, 8 bits per axis over the chunk's own extent), so that 8 consecutive rays form a
// compact angular tile. A scan delivered column by column (8 channels of one column = a thin line)
// then fills packets with 2 x 4 neighbourhoods, which share far more BVH nodes. Two radix passes,
// all in cache; the results do not depend on the order.
void tile_order(const float* rays, std::size_t begin, std::size_t end, std::uint16_t* order) {
  const std::size_t m = end - begin;
  float uv[2][kChunk];
  float lo[2] = {2.0f, 2.0f}, hi[2] = {-2.0f, -2.0f};
  for (std::size_t i = 0; i < m; ++i) {
    const float* d = rays + 6 * (begin + i) + 3;
    const float inv = 1.0f / (std::abs(d[0]) + std::abs(d[1]) + std::abs(d[2]));
    float u = d[0] * inv, v = d[1] * inv;
    if (d[2] < 0.0f) {
      const float uu = (1.0f - std::abs(v)) * (u >= 0.0f ? 1.0f : -1.0f);
      v = (1.0f - std::abs(u)) * (v >= 0.0f ? 1.0f : -1.0f);
      u = uu;
    }
    uv[0][i] = u;
    uv[1][i] = v;
    lo[0] = std::min(lo[0], u);
    hi[0] = std::max(hi[0], u);
    lo[1] = std::min(lo[1], v);
    hi[1] = std::max(hi[1], v);
  }
  // One scale for both axes keeps tiles square in angle.
  const float extent = std::max(hi[0] - lo[0], hi[1] - lo[1]);
  const float scale = extent > 0.0f ? 255.0f / extent : 0.0f;
  std::uint16_t key[2][kChunk];
  std::uint16_t idx[2][kChunk];
  for (std::size_t i = 0; i < m; ++i) {
    const auto qu = static_cast<std::uint32_t>(std::min((uv[0][i] - lo[0]) * scale, 255.0f));
    const auto qv = static_cast<std::uint32_t>(std::min((uv[1][i] - lo[1]) * scale, 255.0f));
    key[0][i] = static_cast<std::uint16_t>(spread16(qu) | (spread16(qv) << 1));
    idx[0][i] = static_cast<std::uint16_t>(i);
  }
  int src = 0;
  for (int shift = 0; shift < 16; shift += 8) {
    std::uint32_t count[256] = {};
    for (std::size_t i = 0; i < m; ++i) ++count[(key[src][i] >> shift) & 255u];
    std::uint32_t sum = 0;
    for (auto& c : count) {
      const std::uint32_t t = c;
      c = sum;
      sum += t;
    }
    for (std::size_t i = 0; i < m; ++i) {
      const std::uint32_t dst = count[(key[src][i] >> shift) & 255u]++;
      key[1 - src][dst] = key[src][i];
      idx[1 - src][dst] = idx[src][i];
    }
    src = 1 - src;
  }
  std::copy(idx[src], idx[src] + m, order);
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

}  // namespace

struct RaycastScene::Impl {
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  std::size_t geometries = 0;
  std::size_t triangles = 0;
  mutable std::mutex commit_mutex;
  mutable bool dirty = true;
  // Embree forbids changing a scene while it is traversed: casts share this lock, additions own it.
  mutable std::shared_mutex scene_mutex;

  Impl() {
    device = rtcNewDevice(nullptr);
    if (!device) throw std::runtime_error("Embree: rtcNewDevice failed (error " +
                                          std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))) + ")");
    scene = rtcNewScene(device);
    // A better BVH costs build time once and pays back on every ray of every frame.
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    // Watertight: a ray through a shared edge or vertex never slips between two triangles.
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
  }
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (device) rtcReleaseDevice(device);
  }
  void commit() const {
    std::lock_guard<std::mutex> lock(commit_mutex);
    if (dirty) {
      rtcCommitScene(scene);
      dirty = false;
    }
  }
};

RaycastScene::RaycastScene() : impl_(std::make_unique<Impl>()) {}
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
  std::unique_lock<std::shared_mutex> no_casts(impl_->scene_mutex);
  const unsigned id = rtcAttachGeometry(impl_->scene, g);
  rtcReleaseGeometry(g);
  std::lock_guard<std::mutex> lock(impl_->commit_mutex);
  impl_->dirty = true;
  impl_->geometries += 1;
  impl_->triangles += nt;
  return {SceneStatus::kOk, 0, id};
}

SceneResult RaycastScene::cast_rays(const float* rays, std::size_t n, const RayHits& out, int nthreads,
                                    RayOrder order) const {
  for (std::size_t i = 0; i < n; ++i) {
    const float* r = rays + 6 * i;
    if (!(std::isfinite(r[0]) && std::isfinite(r[1]) && std::isfinite(r[2]) && std::isfinite(r[3]) &&
          std::isfinite(r[4]) && std::isfinite(r[5]))) {
      return {SceneStatus::kNonFiniteRay, i, kInvalidId};
    }
    if (r[3] == 0.0f && r[4] == 0.0f && r[5] == 0.0f) return {SceneStatus::kZeroDirection, i, kInvalidId};
  }
  std::shared_lock<std::shared_mutex> no_additions(impl_->scene_mutex);
  impl_->commit();
  const bool coherent = order == RayOrder::kCoherent || (order == RayOrder::kAuto && looks_coherent(rays, n));
  RTCScene scene = impl_->scene;
  const std::size_t chunks = (n + kChunk - 1) / kChunk;
  // Tiling pays where the BVH outgrows the caches; on small scenes it costs more than it saves.
  const bool tiles = order == RayOrder::kAuto && impl_->triangles >= kTileMinTriangles;
  auto work = [&](std::size_t c) {
    const std::size_t begin = c * kChunk;
    const std::size_t end = std::min(n, begin + kChunk);
    if (coherent && tiles) {
      std::uint16_t local[kChunk];
      tile_order(rays, begin, end, local);
      cast_packets8(scene, rays, begin, end, out, local);
    } else if (coherent) {
      cast_packets8(scene, rays, begin, end, out);
    } else {
      cast_single(scene, rays, begin, end, out);
    }
  };
  if (chunks <= 1 || nthreads == 1) {
    for (std::size_t c = 0; c < chunks; ++c) work(c);
  } else {
    ThreadPool::instance().parallel_for(chunks, nthreads, work);
  }
  return {};
}

std::size_t RaycastScene::num_geometries() const { return impl_->geometries; }
std::size_t RaycastScene::num_triangles() const { return impl_->triangles; }

}  // namespace cufund::lidar
