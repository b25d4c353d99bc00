// RaycastScene against analytic geometry: an axis-aligned box and a plane, hit distances, normals,
// ids, misses, packet and single-ray paths agreeing, and bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

#include "raycast_scene.h"

namespace cufund::lidar {
namespace {

struct Mesh {
  std::vector<float> v;
  std::vector<std::uint32_t> t;
};

// Axis-aligned box [lo, hi], outward-facing triangles.
Mesh box(float lx, float ly, float lz, float hx, float hy, float hz) {
  Mesh m;
  for (int i = 0; i < 8; ++i) {
    m.v.push_back(i & 1 ? hx : lx);
    m.v.push_back(i & 2 ? hy : ly);
    m.v.push_back(i & 4 ? hz : lz);
  }
  m.t = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
  return m;
}

struct Result {
  std::vector<float> t, uv, n;
  std::vector<std::uint32_t> g, p;
  explicit Result(std::size_t k) : t(k), uv(2 * k), n(3 * k), g(k), p(k) {}
  RayHits hits() { return {t.data(), g.data(), p.data(), uv.data(), n.data()}; }
};

TEST(RaycastScene, BoxFacesAtAnalyticDistances) {
  RaycastScene scene;
  Mesh b = box(-1, -2, -3, 1, 2, 3);
  ASSERT_EQ(scene.add_triangles(b.v.data(), 8, b.t.data(), 12).status, SceneStatus::kOk);
  // From the centre towards +x, -y, +z, and a diagonal direction of length 2.
  std::vector<float> rays = {0, 0, 0, 1, 0, 0, 0, 0, 0, 0, -1, 0, 0.2f, 0.3f, 0, 0, 0, 1, 0, 0, 0, 0, 0, 2};
  Result r(4);
  ASSERT_EQ(scene.cast_rays(rays.data(), 4, r.hits(), 1).status, SceneStatus::kOk);
  EXPECT_FLOAT_EQ(r.t[0], 1.0f);
  EXPECT_FLOAT_EQ(r.t[1], 2.0f);
  EXPECT_FLOAT_EQ(r.t[2], 3.0f);
  EXPECT_FLOAT_EQ(r.t[3], 1.5f);  // t is in units of |direction|
  for (int i = 0; i < 4; ++i) EXPECT_EQ(r.g[i], 0u);
  // Outward normals (triangles wound counter-clockwise seen from outside): +x, -y, +z faces.
  EXPECT_NEAR(r.n[0], 1.0f, 1e-6f);
  EXPECT_NEAR(r.n[4], -1.0f, 1e-6f);
  EXPECT_NEAR(r.n[8], 1.0f, 1e-6f);
}

TEST(RaycastScene, MissIsInfinityAndInvalidIds) {
  RaycastScene scene;
  Mesh b = box(0, 0, 0, 1, 1, 1);
  scene.add_triangles(b.v.data(), 8, b.t.data(), 12);
  std::vector<float> rays = {5, 5, 5, 1, 0, 0};
  Result r(1);
  ASSERT_EQ(scene.cast_rays(rays.data(), 1, r.hits()).status, SceneStatus::kOk);
  EXPECT_TRUE(std::isinf(r.t[0]));
  EXPECT_EQ(r.g[0], kInvalidId);
  EXPECT_EQ(r.p[0], kInvalidId);
}

TEST(RaycastScene, EmptySceneMissesEverything) {
  RaycastScene scene;
  std::vector<float> rays = {0, 0, 0, 1, 0, 0};
  Result r(1);
  ASSERT_EQ(scene.cast_rays(rays.data(), 1, r.hits()).status, SceneStatus::kOk);
  EXPECT_TRUE(std::isinf(r.t[0]));
}

TEST(RaycastScene, GeometryIdsCountFromZeroAndNearestWins) {
  RaycastScene scene;
  Mesh far = box(4, -1, -1, 5, 1, 1);
  Mesh near = box(2, -1, -1, 3, 1, 1);
  EXPECT_EQ(scene.add_triangles(far.v.data(), 8, far.t.data(), 12).id, 0u);
  EXPECT_EQ(scene.add_triangles(near.v.data(), 8, near.t.data(), 12).id, 1u);
  std::vector<float> rays = {0, 0, 0, 1, 0, 0};
  Result r(1);
  scene.cast_rays(rays.data(), 1, r.hits());
  EXPECT_EQ(r.g[0], 1u);
  EXPECT_FLOAT_EQ(r.t[0], 2.0f);
  EXPECT_EQ(scene.num_geometries(), 2u);
  EXPECT_EQ(scene.num_triangles(), 24u);
}

// A scene instancing another reports the base's own geometry ids and its own meshes after them, with the hits of a
// scene holding copies of all the meshes (boxes kept apart: no coplanar faces, no ties).
TEST(RaycastScene, InstancedBaseCastsAsCopiedMeshes) {
  std::vector<Mesh> base_meshes, own_meshes;
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> at(-20.0f, 20.0f), size(0.3f, 2.0f);
  for (int k = 0; k < 30; ++k) {
    const float x = at(rng), y = at(rng), z = 0.1f * static_cast<float>(k), sx = size(rng), sy = size(rng);
    (k < 25 ? base_meshes : own_meshes).push_back(box(x, y, z, x + sx, y + sy, z + 1.0f + 0.01f * k));
  }
  RaycastScene base, copied;
  for (const Mesh& m : base_meshes) {
    ASSERT_EQ(base.add_triangles(m.v.data(), 8, m.t.data(), 12).status, SceneStatus::kOk);
    copied.add_triangles(m.v.data(), 8, m.t.data(), 12);
  }
  RaycastScene view(RaycastScene::Instancing{}, base);
  EXPECT_EQ(view.num_geometries(), base_meshes.size());
  for (std::size_t k = 0; k < own_meshes.size(); ++k) {
    const Mesh& m = own_meshes[k];
    EXPECT_EQ(view.add_triangles(m.v.data(), 8, m.t.data(), 12).id, base_meshes.size() + k);
    copied.add_triangles(m.v.data(), 8, m.t.data(), 12);
  }
  EXPECT_EQ(view.num_geometries(), copied.num_geometries());
  EXPECT_EQ(view.num_triangles(), copied.num_triangles());
  const std::size_t n = 20000;
  std::vector<float> rays(6 * n);
  std::normal_distribution<float> dir(0.0f, 1.0f);
  for (std::size_t i = 0; i < n; ++i) {
    rays[6 * i] = at(rng);
    rays[6 * i + 1] = at(rng);
    rays[6 * i + 2] = 1.5f;
    for (int k = 3; k < 6; ++k) rays[6 * i + k] = dir(rng);
  }
  std::size_t own_hits = 0;
  for (RayOrder order : {RayOrder::kIncoherent, RayOrder::kCoherent, RayOrder::kSorted}) {
    Result a(n), b(n);
    ASSERT_EQ(view.cast_rays(rays.data(), n, a.hits(), 1, order).status, SceneStatus::kOk);
    ASSERT_EQ(copied.cast_rays(rays.data(), n, b.hits(), 1, order).status, SceneStatus::kOk);
    EXPECT_EQ(std::memcmp(a.t.data(), b.t.data(), n * sizeof(float)), 0);
    EXPECT_EQ(a.g, b.g);
    EXPECT_EQ(a.p, b.p);
    EXPECT_EQ(std::memcmp(a.uv.data(), b.uv.data(), 2 * n * sizeof(float)), 0);
    EXPECT_EQ(std::memcmp(a.n.data(), b.n.data(), 3 * n * sizeof(float)), 0);
    own_hits = static_cast<std::size_t>(
        std::count_if(a.g.begin(), a.g.end(), [&](std::uint32_t g) { return g >= 25 && g != kInvalidId; }));
  }
  EXPECT_GT(own_hits, 100u);  // both the base's and the view's own meshes are hit
  // the base can no longer change (Embree must not rebuild a scene the view traverses): refused, nothing added
  EXPECT_EQ(base.add_triangles(own_meshes[0].v.data(), 8, own_meshes[0].t.data(), 12).status, SceneStatus::kInstanced);
  EXPECT_EQ(base.num_geometries(), base_meshes.size());
  // an empty base: the view holds its own meshes only, from id 0
  RaycastScene empty;
  RaycastScene alone(RaycastScene::Instancing{}, empty);
  EXPECT_EQ(alone.add_triangles(own_meshes[0].v.data(), 8, own_meshes[0].t.data(), 12).id, 0u);
}

TEST(RaycastScene, PlaneRangesMatchAnalyticForManyRays) {
  // Ground plane z = 0 (two big triangles), rays from (0, 0, h) downwards at random angles:
  // t = h / -dz exactly.
  RaycastScene scene;
  const float L = 1000.0f;
  std::vector<float> v = {-L, -L, 0, L, -L, 0, L, L, 0, -L, L, 0};
  std::vector<std::uint32_t> t = {0, 1, 2, 0, 2, 3};
  scene.add_triangles(v.data(), 4, t.data(), 2);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> ang(0.0f, 6.2831853f), el(0.2f, 1.5f);
  const std::size_t n = 5000;
  const float h = 1.7f;
  std::vector<float> rays(6 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const float a = ang(rng), e = el(rng);
    float* r = &rays[6 * i];
    r[0] = 0;
    r[1] = 0;
    r[2] = h;
    r[3] = std::cos(e) * std::cos(a);
    r[4] = std::cos(e) * std::sin(a);
    r[5] = -std::sin(e);
  }
  for (RayOrder order : {RayOrder::kIncoherent, RayOrder::kCoherent, RayOrder::kSorted}) {
    Result r(n);
    ASSERT_EQ(scene.cast_rays(rays.data(), n, r.hits(), 2, order).status, SceneStatus::kOk);
    for (std::size_t i = 0; i < n; ++i) {
      const double expect = h / -static_cast<double>(rays[6 * i + 5]);
      ASSERT_NEAR(r.t[i], expect, 1e-5 * expect) << i;
      ASSERT_NEAR(r.n[3 * i + 2], 1.0f, 1e-6f);
    }
  }
}

TEST(RaycastScene, PacketAndSingleRayPathsAgree) {
  RaycastScene scene;
  Mesh a = box(-3, -3, -1, 3, 3, 4);
  Mesh b = box(0.5f, 0.5f, 0, 1.5f, 2.5f, 1);
  scene.add_triangles(a.v.data(), 8, a.t.data(), 12);
  scene.add_triangles(b.v.data(), 8, b.t.data(), 12);
  std::mt19937 rng(3);
  std::normal_distribution<float> g(0.0f, 1.0f);
  const std::size_t n = 3001;  // not a multiple of the packet width
  std::vector<float> rays(6 * n);
  for (std::size_t i = 0; i < n; ++i) {
    float* r = &rays[6 * i];
    r[0] = 0.1f;
    r[1] = 0.2f;
    r[2] = 0.3f;
    r[3] = g(rng);
    r[4] = g(rng);
    r[5] = g(rng);
  }
  Result s(n), p(n);
  scene.cast_rays(rays.data(), n, s.hits(), 1, RayOrder::kIncoherent);
  scene.cast_rays(rays.data(), n, p.hits(), 2, RayOrder::kCoherent);
  EXPECT_EQ(s.g, p.g);
  EXPECT_EQ(s.p, p.p);
  for (std::size_t i = 0; i < n; ++i) ASSERT_NEAR(s.t[i], p.t[i], 1e-6f * s.t[i]) << i;
}

TEST(RaycastScene, OccludedIsWhetherCastRaysHits) {
  RaycastScene scene;
  Mesh a = box(0.5f, 0.5f, 0, 1.5f, 2.5f, 1);
  Mesh b = box(-2, -1, -1, -1, 1, 3);
  scene.add_triangles(a.v.data(), 8, a.t.data(), 12);
  scene.add_triangles(b.v.data(), 8, b.t.data(), 12);
  std::mt19937 rng(5);
  std::normal_distribution<float> g(0.0f, 1.0f);
  const std::size_t n = 3001;  // rays from scattered origins, not a multiple of the packet width
  std::vector<float> rays(6 * n);
  for (float& x : rays) x = g(rng);
  Result hit(n);
  scene.cast_rays(rays.data(), n, hit.hits(), 1, RayOrder::kIncoherent);
  std::vector<std::uint8_t> occ(n, 7);
  ASSERT_EQ(scene.occluded(rays.data(), n, occ.data(), 2).status, SceneStatus::kOk);
  std::size_t hits = 0;
  for (std::size_t i = 0; i < n; ++i) {
    ASSERT_EQ(occ[i], std::isfinite(hit.t[i]) ? 1 : 0) << i;
    hits += occ[i];
  }
  EXPECT_GT(hits, n / 10);  // both answers occur
  EXPECT_LT(hits, n - n / 10);

  std::vector<float> bad = {0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0};
  const SceneResult r = scene.occluded(bad.data(), 2, occ.data());
  EXPECT_EQ(r.status, SceneStatus::kZeroDirection);
  EXPECT_EQ(r.index, 1u);
}

// UV sphere of radius r around the origin: rings x segs quads split in two.
Mesh uv_sphere(float r, int rings, int segs) {
  Mesh m;
  for (int i = 0; i <= rings; ++i) {
    const double th = M_PI * i / rings;
    for (int j = 0; j < segs; ++j) {
      const double ph = 2 * M_PI * j / segs;
      m.v.push_back(static_cast<float>(r * std::sin(th) * std::cos(ph)));
      m.v.push_back(static_cast<float>(r * std::sin(th) * std::sin(ph)));
      m.v.push_back(static_cast<float>(r * std::cos(th)));
    }
  }
  for (int i = 0; i < rings; ++i) {
    for (int j = 0; j < segs; ++j) {
      const std::uint32_t a = i * segs + j, b = i * segs + (j + 1) % segs, c = a + segs, d = b + segs;
      m.t.insert(m.t.end(), {a, c, b, b, c, d});
    }
  }
  return m;
}

bool same_bits(const Result& a, const Result& b) {
  const std::size_t k = a.t.size();
  return std::memcmp(a.t.data(), b.t.data(), 4 * k) == 0 && std::memcmp(a.uv.data(), b.uv.data(), 8 * k) == 0 &&
         std::memcmp(a.n.data(), b.n.data(), 12 * k) == 0 && a.g == b.g && a.p == b.p;
}

class SortedPackets : public ::testing::TestWithParam<int> {};

TEST_P(SortedPackets, MatchSingleRaysBitForBit) {
  // Random rays in and around a sphere and a box: the sorted path regroups them completely, yet
  // every output of every ray must equal the single-ray path's, on any thread count. 6400 and
  // 51200 triangles: keyed by heading and by box crossing.
  RaycastScene scene;
  Mesh s = uv_sphere(3.0f, GetParam(), 2 * GetParam());
  Mesh b = box(0.5f, 0.5f, 0, 1.5f, 2.5f, 1);
  scene.add_triangles(s.v.data(), s.v.size() / 3, s.t.data(), s.t.size() / 3);
  scene.add_triangles(b.v.data(), 8, b.t.data(), 12);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> o(-4.0f, 4.0f);
  std::normal_distribution<float> g(0.0f, 1.0f);
  const std::size_t n = 20001;  // several chunks, not a multiple of the packet width
  std::vector<float> rays(6 * n);
  for (std::size_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) rays[6 * i + k] = o(rng);
    for (int k = 3; k < 6; ++k) rays[6 * i + k] = g(rng);
  }
  Result single(n), sorted1(n), sorted2(n), automatic(n);
  ASSERT_EQ(scene.cast_rays(rays.data(), n, single.hits(), 1, RayOrder::kIncoherent).status, SceneStatus::kOk);
  ASSERT_EQ(scene.cast_rays(rays.data(), n, sorted1.hits(), 1, RayOrder::kSorted).status, SceneStatus::kOk);
  ASSERT_EQ(scene.cast_rays(rays.data(), n, sorted2.hits(), 2, RayOrder::kSorted).status, SceneStatus::kOk);
  ASSERT_EQ(scene.cast_rays(rays.data(), n, automatic.hits(), 0).status, SceneStatus::kOk);
  const auto hits = std::count_if(single.t.begin(), single.t.end(), [](float t) { return std::isfinite(t); });
  EXPECT_GT(hits, static_cast<long>(n / 5));  // about a third: many origins lie outside the sphere
  EXPECT_LT(hits, static_cast<long>(n));
  EXPECT_TRUE(same_bits(single, sorted1));
  EXPECT_TRUE(same_bits(single, sorted2));
  EXPECT_TRUE(same_bits(single, automatic));
  // Only the distances asked for.
  std::vector<float> t(n);
  ASSERT_EQ(scene.cast_rays(rays.data(), n, RayHits{t.data()}, 2, RayOrder::kSorted).status, SceneStatus::kOk);
  EXPECT_EQ(std::memcmp(t.data(), single.t.data(), 4 * n), 0);
}

INSTANTIATE_TEST_SUITE_P(RaycastScene, SortedPackets, ::testing::Values(40, 160));

TEST(RaycastScene, BadInputReportsStatusAndIndex) {
  RaycastScene scene;
  Mesh b = box(0, 0, 0, 1, 1, 1);
  EXPECT_EQ(scene.add_triangles(b.v.data(), 8, b.t.data(), 0).status, SceneStatus::kNoTriangles);
  std::vector<std::uint32_t> bad = b.t;
  bad[3 * 5 + 1] = 8;
  SceneResult r = scene.add_triangles(b.v.data(), 8, bad.data(), 12);
  EXPECT_EQ(r.status, SceneStatus::kIndexOutOfRange);
  EXPECT_EQ(r.index, 5u);
  std::vector<float> nanv = b.v;
  nanv[3 * 6 + 2] = NAN;
  r = scene.add_triangles(nanv.data(), 8, b.t.data(), 12);
  EXPECT_EQ(r.status, SceneStatus::kNonFiniteVertex);
  EXPECT_EQ(r.index, 6u);
  EXPECT_EQ(scene.num_geometries(), 0u);

  std::vector<float> rays = {0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, NAN, 0, 1, 0, 0};
  Result out(3);
  r = scene.cast_rays(rays.data(), 3, out.hits());
  EXPECT_EQ(r.status, SceneStatus::kZeroDirection);
  EXPECT_EQ(r.index, 1u);
  r = scene.cast_rays(rays.data() + 12, 1, out.hits());
  EXPECT_EQ(r.status, SceneStatus::kNonFiniteRay);
}

TEST(RaycastScene, DegenerateTrianglesAreNeverHit) {
  RaycastScene scene;
  std::vector<float> v = {1, -1, -1, 1, 1, -1, 1, 1, -1, 1, 0, 1};  // v1 == v2: zero area
  std::vector<std::uint32_t> t = {0, 1, 2};
  ASSERT_EQ(scene.add_triangles(v.data(), 4, t.data(), 1).status, SceneStatus::kOk);
  std::vector<float> rays = {0, 0, 0, 1, 0, 0};
  Result r(1);
  scene.cast_rays(rays.data(), 1, r.hits());
  EXPECT_TRUE(std::isinf(r.t[0]));
}

}  // namespace
}  // namespace cufund::lidar
