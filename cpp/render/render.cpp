#include "render.h"

#include "thread_pool.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace cufund::render {

namespace {

constexpr std::size_t kRowsPerChunk = 8;

// The plane coordinates of a point across the dominant axis of its normal: (y, z) facing x, (x, z) facing y,
// (x, y) facing z (cufund.worlds.materials.planar_coords).
inline void planar(const double p[3], const float n[3], double& a, double& b) {
  const float ax = std::fabs(n[0]), ay = std::fabs(n[1]), az = std::fabs(n[2]);
  if (ax >= ay && ax >= az) {
    a = p[1];
    b = p[2];
  } else if (ay >= az) {
    a = p[0];
    b = p[2];
  } else {
    a = p[0];
    b = p[1];
  }
}

}  // namespace

RenderResult render(const lidar::RaycastScene& scene, const View& view, const SurfaceMaterial* materials,
                    std::size_t n_materials, const Tiles& tiles, const Lighting& light, const Frame& out,
                    int nthreads) {
  if (view.width <= 0 || view.height <= 0 || !view.dirs_O || !view.row_p || !view.row_R || !out.rgb || !out.ids)
    return {RenderStatus::kBadView, 0};
  const std::size_t w = static_cast<std::size_t>(view.width), h = static_cast<std::size_t>(view.height);
  const std::size_t n = w * h;
  auto& pool = ThreadPool::instance();
  const std::size_t chunks = (h + kRowsPerChunk - 1) / kRowsPerChunk;

  // the caller's scratch, kept for its next frame (references: the pool's workers must see the caller's buffers,
  // not their own thread_local ones)
  thread_local std::vector<float> tl_rays, tl_t_hit, tl_normals, tl_shadow_rays, tl_direct;
  thread_local std::vector<std::uint32_t> tl_gid, tl_shadow_of;
  thread_local std::vector<std::uint8_t> tl_shadowed;
  auto& rays = tl_rays;
  auto& t_hit = tl_t_hit;
  auto& normals = tl_normals;
  auto& shadow_rays = tl_shadow_rays;
  auto& shadowed = tl_shadowed;
  auto& direct = tl_direct;
  auto& gid = tl_gid;
  auto& shadow_of = tl_shadow_of;
  rays.resize(6 * n);
  t_hit.resize(n);
  normals.resize(3 * n);
  gid.resize(n);

  // primary rays, row by row
  pool.parallel_for(chunks, nthreads, [&](std::size_t c) {
    for (std::size_t r = c * kRowsPerChunk; r < std::min(h, (c + 1) * kRowsPerChunk); ++r) {
      const double* p = view.row_p + 3 * r;
      const double* R = view.row_R + 9 * r;
      for (std::size_t col = 0; col < w; ++col) {
        const std::size_t k = r * w + col;
        const float* d = view.dirs_O + 3 * k;
        float* ray = rays.data() + 6 * k;
        ray[0] = static_cast<float>(p[0]);
        ray[1] = static_cast<float>(p[1]);
        ray[2] = static_cast<float>(p[2]);
        for (int i = 0; i < 3; ++i)
          ray[3 + i] = static_cast<float>(R[3 * i] * d[0] + R[3 * i + 1] * d[1] + R[3 * i + 2] * d[2]);
      }
    }
  });
  lidar::RayHits hits;
  hits.t_hit = t_hit.data();
  hits.geometry_ids = gid.data();
  hits.normals = normals.data();
  const auto cast = scene.cast_rays(rays.data(), n, hits, nthreads, lidar::RayOrder::kCoherent);
  if (cast.status != lidar::SceneStatus::kOk) return {RenderStatus::kBadView, cast.index};
  for (std::size_t k = 0; k < n; ++k)
    if (gid[k] != lidar::kInvalidId && gid[k] >= n_materials) return {RenderStatus::kBadMaterial, gid[k]};

  // each material's seed shift of the shared noise tile, once
  std::vector<double> shift(2 * n_materials, 0.0);
  for (std::size_t g = 0; g < n_materials; ++g)
    if (materials[g].texture != Texture::kChecker) seed_shift(materials[g].seed, shift[2 * g], shift[2 * g + 1]);
  const float* l = light.to_sun;
  direct.resize(n);
  // shading: albedo and the direct term max(0, n.l) (|n.l| without shadows); shadow rays clear it below
  pool.parallel_for(chunks, nthreads, [&](std::size_t c) {
    for (std::size_t k = c * kRowsPerChunk * w; k < std::min(n, (c + 1) * kRowsPerChunk * w); ++k) {
      float* rgb = out.rgb + 3 * k;
      if (gid[k] == lidar::kInvalidId) {
        out.ids[k] = -1;
        for (int i = 0; i < 3; ++i) rgb[i] = light.sky[i];
        direct[k] = 0.0f;
        continue;
      }
      out.ids[k] = static_cast<std::int32_t>(gid[k]);
      const SurfaceMaterial& m = materials[gid[k]];
      const float* ray = rays.data() + 6 * k;
      const float* nrm = normals.data() + 3 * k;
      float f = 1.0f;
      if (m.texture != Texture::kNone && m.texture != Texture::kExternal) {
        const double p[3] = {ray[0] + static_cast<double>(ray[3]) * t_hit[k],
                             ray[1] + static_cast<double>(ray[4]) * t_hit[k],
                             ray[2] + static_cast<double>(ray[5]) * t_hit[k]};
        double a, b;
        planar(p, nrm, a, b);
        const float* tile = (m.tile >= 0 && m.tile < tiles.count)
                                ? tiles.data + static_cast<std::size_t>(m.tile) * tiles.size * tiles.size
                                : nullptr;
        if (tile || m.texture == Texture::kChecker)
          f = pattern_shifted(m.texture, (a + m.offset[0]) / m.scale + shift[2 * gid[k]],
                              (b + m.offset[1]) / m.scale + shift[2 * gid[k] + 1], tile, tiles.size, m.seed);
      }
      for (int i = 0; i < 3; ++i) rgb[i] = m.dark[i] + (m.albedo[i] - m.dark[i]) * f;
      float ndl = nrm[0] * l[0] + nrm[1] * l[1] + nrm[2] * l[2];
      if (!light.shadows) {
        ndl = std::fabs(ndl);
      } else if (nrm[0] * ray[3] + nrm[1] * ray[4] + nrm[2] * ray[5] > 0.0f) {
        ndl = -ndl;  // the normal facing the camera
      }
      direct[k] = std::max(ndl, 0.0f);
    }
  });

  if (light.shadows) {
    // one shadow ray towards the sun from every lit hit, lifted off the surface along its camera-facing normal
    shadow_of.clear();
    for (std::size_t k = 0; k < n; ++k)
      if (direct[k] > 0.0f) shadow_of.push_back(static_cast<std::uint32_t>(k));
    const std::size_t m = shadow_of.size();
    if (m > 0) {
      shadow_rays.resize(6 * m);
      shadowed.resize(m);
      constexpr std::size_t kShadowChunk = 4096;
      pool.parallel_for((m + kShadowChunk - 1) / kShadowChunk, nthreads, [&](std::size_t c) {
        for (std::size_t j = c * kShadowChunk; j < std::min(m, (c + 1) * kShadowChunk); ++j) {
          const std::size_t k = shadow_of[j];
          const float* ray = rays.data() + 6 * k;
          const float* nrm = normals.data() + 3 * k;
          const float side = (nrm[0] * ray[3] + nrm[1] * ray[4] + nrm[2] * ray[5] > 0.0f) ? -1.0f : 1.0f;
          const float len = std::sqrt(ray[3] * ray[3] + ray[4] * ray[4] + ray[5] * ray[5]);
          const float eps = 1e-4f * (1.0f + t_hit[k] * len);
          float* s = shadow_rays.data() + 6 * j;
          for (int i = 0; i < 3; ++i) {
            s[i] = ray[i] + ray[3 + i] * t_hit[k] + side * nrm[i] * eps;
            s[3 + i] = l[i];
          }
        }
      });
      // any hit towards the sun shadows the pixel: an occlusion query, not a closest-hit cast
      const auto r = scene.occluded(shadow_rays.data(), m, shadowed.data(), nthreads);
      if (r.status != lidar::SceneStatus::kOk) return {RenderStatus::kBadView, r.index};
      for (std::size_t j = 0; j < m; ++j)
        if (shadowed[j]) direct[shadow_of[j]] = 0.0f;
    }
  }
  const float amb = light.ambient;
  pool.parallel_for(chunks, nthreads, [&](std::size_t c) {
    for (std::size_t k = c * kRowsPerChunk * w; k < std::min(n, (c + 1) * kRowsPerChunk * w); ++k) {
      if (out.ids[k] < 0) {
        if (out.shade) out.shade[k] = 0.0f;
        continue;
      }
      const float shade = amb + (1.0f - amb) * direct[k];
      if (out.shade) out.shade[k] = shade;
      for (int i = 0; i < 3; ++i) out.rgb[3 * k + i] *= shade;
    }
  });
  return {RenderStatus::kOk, 0};
}

}  // namespace cufund::render
