// The renderer against analytic scenes: a floor seen from above (checker squares where the pattern says, Lambert
// shade = ambient + (1 - ambient) n.l), a box's shadow on the floor where the sun's projection puts it, and bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "render.h"

namespace cufund::render {
namespace {

void add_quad(lidar::RaycastScene& s, float z, float half) {
  const float v[] = {-half, -half, z, half, -half, z, half, half, z, -half, half, z};
  const std::uint32_t t[] = {0, 1, 2, 0, 2, 3};
  s.add_triangles(v, 4, t, 2);
}

void add_box(lidar::RaycastScene& s, float lx, float ly, float lz, float hx, float hy, float hz) {
  std::vector<float> v;
  for (int i = 0; i < 8; ++i) {
    v.push_back(i & 1 ? hx : lx);
    v.push_back(i & 2 ? hy : ly);
    v.push_back(i & 4 ? hz : lz);
  }
  const std::uint32_t t[] = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                             2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
  s.add_triangles(v.data(), 8, t, 12);
}

// A camera 10 m above the origin looking straight down: pixel (r, c) sees the floor point
// x = -(r - cy) / f * 10, y = -(c - cx) / f * 10 (optical x right = world -y, y down = world -x).
struct DownCamera {
  int w = 64, h = 64;
  double f = 64.0, cx = 31.5, cy = 31.5;
  std::vector<float> dirs;
  std::vector<double> p, R;
  DownCamera() {
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c) {
        dirs.push_back(static_cast<float>((c - cx) / f));
        dirs.push_back(static_cast<float>((r - cy) / f));
        dirs.push_back(1.0f);
      }
    for (int r = 0; r < h; ++r) {
      p.insert(p.end(), {0.0, 0.0, 10.0});
      // columns: optical x -> world -y, y -> world -x, z -> world -z
      R.insert(R.end(), {0, -1, 0, -1, 0, 0, 0, 0, -1});
    }
  }
  View view() const { return {dirs.data(), w, h, p.data(), R.data()}; }
  double floor_x(int r) const { return -(r - cy) / f * 10.0; }
  double floor_y(int c) const { return -(c - cx) / f * 10.0; }
};

TEST(Render, CheckerAndLambertShadeOnAFloor) {
  lidar::RaycastScene scene;
  add_quad(scene, 0.0f, 50.0f);
  SurfaceMaterial m;
  m.texture = Texture::kChecker;
  m.scale = 1.0f;
  for (int i = 0; i < 3; ++i) {
    m.albedo[i] = 0.8f;
    m.dark[i] = 0.2f;
  }
  Lighting light;
  const float s = 1.0f / std::sqrt(2.0f);
  light.to_sun[0] = s;
  light.to_sun[2] = s;  // 45 degrees: n.l = 1/sqrt(2)
  light.ambient = 0.25f;
  light.shadows = true;
  DownCamera cam;
  std::vector<float> rgb(3 * cam.w * cam.h), shade(cam.w * cam.h);
  std::vector<std::int32_t> ids(cam.w * cam.h);
  Tiles tiles;
  ASSERT_EQ(render(scene, cam.view(), &m, 1, tiles, light, {rgb.data(), ids.data(), shade.data()}, 2).status,
            RenderStatus::kOk);
  const float expect_shade = 0.25f + 0.75f * s;
  int checked = 0;
  for (int r = 0; r < cam.h; ++r)
    for (int c = 0; c < cam.w; ++c) {
      const double x = cam.floor_x(r), y = cam.floor_y(c);
      if (std::fabs(x - std::round(x)) < 0.1 || std::fabs(y - std::round(y)) < 0.1) continue;  // near an edge
      const bool bright = ((static_cast<long>(std::floor(x)) + static_cast<long>(std::floor(y))) & 1) == 0;
      const int k = r * cam.w + c;
      EXPECT_EQ(ids[k], 0);
      EXPECT_NEAR(shade[k], expect_shade, 1e-5);
      EXPECT_NEAR(rgb[3 * k], (bright ? 0.8f : 0.2f) * expect_shade, 1e-5) << r << "," << c;
      ++checked;
    }
  EXPECT_GT(checked, 2000);
}

TEST(Render, ABoxShadowsTheFloorWhereTheSunProjectsIt) {
  lidar::RaycastScene scene;
  add_quad(scene, 0.0f, 50.0f);
  add_box(scene, -0.5f, -0.5f, 0.0f, 0.5f, 0.5f, 1.0f);  // a 1 m cube on the floor
  SurfaceMaterial mats[2];
  Lighting light;
  // sun towards +x at 45 degrees: the cube's shadow covers x in [-1.5, -0.5] beside it (|y| < 0.5)
  const float s = 1.0f / std::sqrt(2.0f);
  light.to_sun[0] = s;
  light.to_sun[1] = 0.0f;
  light.to_sun[2] = s;
  light.ambient = 0.2f;
  light.shadows = true;
  DownCamera cam;
  std::vector<float> rgb(3 * cam.w * cam.h), shade(cam.w * cam.h);
  std::vector<std::int32_t> ids(cam.w * cam.h);
  ASSERT_EQ(render(scene, cam.view(), mats, 2, Tiles{}, light, {rgb.data(), ids.data(), shade.data()}, 2).status,
            RenderStatus::kOk);
  int in = 0, out = 0;
  for (int r = 0; r < cam.h; ++r)
    for (int c = 0; c < cam.w; ++c) {
      const int k = r * cam.w + c;
      if (ids[k] != 0) continue;  // the cube itself
      // where the floor point's ray towards the sun enters the cube: x in (-1.5, -0.5) - margin, |y| < 0.5
      const double x = cam.floor_x(r), y = cam.floor_y(c);
      const bool shadow = x > -1.5 && x < -0.5 && std::fabs(y) < 0.5;
      const bool far = x < -1.6 || x > -0.4 || std::fabs(y) > 0.6;
      if (shadow && x > -1.4 && std::fabs(y) < 0.4) {
        EXPECT_NEAR(shade[k], 0.2f, 1e-6);
        ++in;
      } else if (far) {
        EXPECT_NEAR(shade[k], 0.2f + 0.8f * s, 1e-5);
        ++out;
      }
    }
  EXPECT_GT(in, 20);
  EXPECT_GT(out, 1000);
}

TEST(Render, BadInputIsReported) {
  lidar::RaycastScene scene;
  add_quad(scene, 0.0f, 50.0f);
  DownCamera cam;
  std::vector<float> rgb(3 * cam.w * cam.h);
  std::vector<std::int32_t> ids(cam.w * cam.h);
  Lighting light;
  // no material row for geometry 0
  EXPECT_EQ(render(scene, cam.view(), nullptr, 0, Tiles{}, light, {rgb.data(), ids.data(), nullptr}, 1).status,
            RenderStatus::kBadMaterial);
  View bad = cam.view();
  bad.width = 0;
  SurfaceMaterial m;
  EXPECT_EQ(render(scene, bad, &m, 1, Tiles{}, light, {rgb.data(), ids.data(), nullptr}, 1).status,
            RenderStatus::kBadView);
}

TEST(Textures, PatternsStayInTheUnitIntervalAndCheckerAlternates) {
  std::vector<float> tile(16 * 16);
  for (std::size_t i = 0; i < tile.size(); ++i) tile[i] = static_cast<float>(i % 7) / 6.0f;
  for (double a = -3.0; a < 3.0; a += 0.173)
    for (double b = -3.0; b < 3.0; b += 0.191)
      for (auto t : {Texture::kNoise, Texture::kBrick, Texture::kBark, Texture::kConcrete}) {
        const float f = pattern(t, a, b, tile.data(), 16, 7);
        EXPECT_GE(f, 0.0f);
        EXPECT_LE(f, 1.0f);
      }
  EXPECT_EQ(pattern(Texture::kChecker, 0.5, 0.5, nullptr, 0, 0), 1.0f);
  EXPECT_EQ(pattern(Texture::kChecker, 1.5, 0.5, nullptr, 0, 0), 0.0f);
  EXPECT_EQ(pattern(Texture::kChecker, -0.5, 0.5, nullptr, 0, 0), 0.0f);
  EXPECT_EQ(pattern(Texture::kChecker, -0.5, -0.5, nullptr, 0, 0), 1.0f);
  // the tile repeats every period and interpolates between texels
  EXPECT_FLOAT_EQ(tile_lookup(tile.data(), 16, 0.25, 0.5), tile_lookup(tile.data(), 16, 1.25, -0.5));
  EXPECT_FLOAT_EQ(tile_lookup(tile.data(), 16, 0.5 / 16, 0.0), 0.5f * (tile[0] + tile[1]));
}

}  // namespace
}  // namespace cufund::render
