// The camera renderer: primary rays of a pinhole (any lens: the caller gives each pixel's direction) through the
// world's Embree scene (the LiDAR's RaycastScene: one BVH per world), Lambertian shading of each hit's material
// under a sun and ambient light, and hard shadows (one shadow ray per lit pixel). Rays are cast in coherent
// 8-wide packets, shading runs on cufund's thread pool.
#pragma once

#include "raycast_scene.h"
#include "textures.h"

#include <cstddef>
#include <cstdint>

namespace cufund::render {

// How cameras see one geometry of the scene (index = geometry id).
struct SurfaceMaterial {
  Texture texture = Texture::kNone;
  float albedo[3] = {0.7f, 0.7f, 0.7f};  // where the pattern is 1
  float dark[3] = {0.0f, 0.0f, 0.0f};    // where the pattern is 0
  float scale = 1.0f;                    // [m] per pattern unit
  std::uint32_t seed = 0;
  std::int32_t tile = -1;          // index into the noise tiles (noise-based textures)
  float offset[2] = {0.0f, 0.0f};  // shift of the plane coordinates [m]
};

struct Tiles {
  const float* data = nullptr;  // count x size x size
  int count = 0;
  int size = 0;
};

struct Lighting {
  float to_sun[3] = {0.0f, 0.0f, 1.0f};  // unit direction towards the sun, world frame
  float ambient = 0.3f;
  bool shadows = false;  // max(0, n.l) with the normal facing the camera and a shadow ray; else |n.l|, no rays
  float sky[3] = {0.55f, 0.7f, 0.9f};
};

// One image: pixel k = row * width + col looks along dirs_O[k] (optical frame), row r taken from the camera pose
// (row_p[r], row_R[r]) = (p_WO, R_WO row-major): all rows equal for a global shutter.
struct View {
  const float* dirs_O = nullptr;  // (H * W, 3)
  int width = 0, height = 0;
  const double* row_p = nullptr;  // (H, 3)
  const double* row_R = nullptr;  // (H, 3, 3)
};

struct Frame {
  float* rgb = nullptr;         // (H * W, 3) linear colour
  std::int32_t* ids = nullptr;  // (H * W,) geometry id, -1 where nothing is hit
  float* shade = nullptr;       // (H * W,) optional: ambient + (1 - ambient) * direct, 0 on the sky
};

enum class RenderStatus { kOk, kBadView, kBadMaterial };

struct RenderResult {
  RenderStatus status = RenderStatus::kOk;
  std::size_t index = 0;  // the offending geometry id for kBadMaterial
};

// Renders one view. Geometries without an entry in `materials` (id >= n_materials) are kBadMaterial.
// nthreads <= 0 uses the shared pool's threads.
RenderResult render(const lidar::RaycastScene& scene, const View& view, const SurfaceMaterial* materials,
                    std::size_t n_materials, const Tiles& tiles, const Lighting& light, const Frame& out,
                    int nthreads = 0);

}  // namespace cufund::render
