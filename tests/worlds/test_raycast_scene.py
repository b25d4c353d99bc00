"""cufund.sensors.RaycastScene against analytic geometry and Open3D's RaycastingScene."""

import numpy as np
import pytest

import cufund
from cufund.sensors import INVALID_ID, RaycastScene
from cufund.worlds import primitives


def _scene(*meshes):
    scene = RaycastScene()
    for v, f in meshes:
        scene.add_triangles(v, f)
    return scene


def _random_directions(rng, n):
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_plane_ranges_are_height_over_sine_of_depression():
    scene = _scene(primitives.plane((1000.0, 1000.0)))
    rng = np.random.default_rng(0)
    n = 2000
    el = rng.uniform(0.1, 1.5, n)
    az = rng.uniform(0, 2 * np.pi, n)
    h = 2.5
    rays = np.column_stack(
        [np.zeros(n), np.zeros(n), np.full(n, h), np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), -np.sin(el)]
    ).astype(np.float32)
    out = scene.cast_rays(rays)
    np.testing.assert_allclose(out["t_hit"], h / -rays[:, 5].astype(np.float64), rtol=2e-6)
    np.testing.assert_allclose(out["normals"], np.tile([0.0, 0.0, 1.0], (n, 1)), atol=1e-6)  # plane() faces +z
    assert np.all(out["geometry_ids"] == 0)


def test_sphere_ranges_match_the_analytic_sphere_within_tessellation_error():
    r = 2.0
    v, f = primitives.sphere(r, subdivisions=5)
    scene = _scene((v, f))
    rng = np.random.default_rng(1)
    n = 5000
    d = _random_directions(rng, n)
    o = rng.uniform(-0.5, 0.5, (n, 3))
    rays = np.column_stack([o, d]).astype(np.float32)
    t = scene.cast_rays(rays)["t_hit"].astype(np.float64)
    # analytic: |o + t d| = r
    b = np.sum(o * d, 1)
    t_exact = -b + np.sqrt(b * b - (np.sum(o * o, 1) - r * r))
    # inscribed polyhedron: hits are inside the sphere, by less than the sagitta of an edge
    edge = np.max(np.linalg.norm(v[f[:, 0]] - v[f[:, 1]], axis=1))
    sagitta = r - np.sqrt(r * r - (edge / np.sqrt(3)) ** 2)
    assert np.all(t <= t_exact + 1e-5)
    assert np.all(t >= t_exact - sagitta / np.min(np.abs(np.sum(d * (o + d * t_exact[:, None]) / r, 1))) - 1e-5)
    assert np.max(t_exact - t) > 0.0  # the mesh is a polyhedron, not the sphere


def test_box_face_distances_ids_and_outward_normals():
    scene = _scene(
        primitives.box((2.0, 4.0, 6.0)),
        (primitives.box((1.0, 1.0, 1.0))[0] + [10, 0, 0], primitives.box((1.0, 1.0, 1.0))[1]),
    )
    rays = np.array(
        [
            [0, 0, 0, 1, 0, 0],
            [0, 0, 0, 0, -1, 0],
            [0, 0, 0, 0, 0, 2],
            [5, 0, 0, 1, 0, 0],
            [5, 0, 0, -1, 0, 0],
            [5, 5, 5, 0, 0, 1],
        ],
        np.float32,
    )
    out = scene.cast_rays(rays)
    np.testing.assert_allclose(out["t_hit"][:5], [1.0, 2.0, 1.5, 4.5, 4.0], rtol=1e-6)
    assert np.isinf(out["t_hit"][5])
    np.testing.assert_array_equal(out["geometry_ids"], [0, 0, 0, 1, 0, INVALID_ID])
    assert out["primitive_ids"][5] == INVALID_ID
    # Inside the first box looking out, Embree's normals of outward-wound faces point back at us.
    n = out["normals"]
    np.testing.assert_allclose(n[3], [-1, 0, 0], atol=1e-6)  # face of box 1 seen from outside
    np.testing.assert_allclose(n[4], [1, 0, 0], atol=1e-6)  # +x face of box 0 seen from outside
    np.testing.assert_array_equal(n[5], [0, 0, 0])


def test_leading_dimensions_are_kept_like_open3d():
    scene = _scene(primitives.plane((10.0, 10.0)))
    rays = np.zeros((4, 5, 6), np.float32)
    rays[..., 2] = 1.0
    rays[..., 5] = -1.0
    out = scene.cast_rays(rays)
    assert out["t_hit"].shape == (4, 5)
    assert out["normals"].shape == (4, 5, 3)
    np.testing.assert_allclose(out["t_hit"], 1.0)


def test_packets_and_single_rays_agree():
    w = cufund.worlds.load("forest", seed=3, n_trees=40)
    rng = np.random.default_rng(2)
    rays = np.column_stack([np.tile([0.0, 0.0, 1.5], (4096, 1)), _random_directions(rng, 4096)]).astype(np.float32)
    a = w.raycast_scene.cast_rays(rays, coherent=True)
    b = w.raycast_scene.cast_rays(rays, coherent=False, nthreads=1)
    np.testing.assert_array_equal(a["geometry_ids"], b["geometry_ids"])
    np.testing.assert_allclose(a["t_hit"], b["t_hit"], rtol=1e-6)


@pytest.mark.parametrize("subdivisions", [5, 6])  # 20480 and 81920 triangles: keyed by heading / box crossing
def test_random_rays_sorted_internally_equal_single_rays_bit_for_bit(subdivisions):
    # A large random batch is sorted and cast in packets (the default); every output of every ray
    # must be the single-ray path's, whatever the thread count.
    v, f = primitives.sphere(3.0, subdivisions=subdivisions)
    scene = _scene((v, f), primitives.box((1.0, 2.0, 0.5)))
    rng = np.random.default_rng(4)
    n = 30001
    rays = np.column_stack([rng.uniform(-3.5, 3.5, (n, 3)), rng.normal(size=(n, 3))]).astype(np.float32)
    single = scene.cast_rays(rays, coherent=False, nthreads=1)
    assert 0.3 < np.isfinite(single["t_hit"]).mean() < 0.9  # origins outside the sphere may miss
    for nthreads in (1, 2, 0):
        auto = scene.cast_rays(rays, nthreads=nthreads)
        for key in single:
            np.testing.assert_array_equal(auto[key], single[key], err_msg=f"{key}, nthreads={nthreads}")


o3d = pytest.importorskip("open3d")


def _both(vertices, triangles):
    ours = RaycastScene()
    ours.add_triangles(vertices, triangles)
    theirs = o3d.t.geometry.RaycastingScene()
    theirs.add_triangles(o3d.core.Tensor(vertices.astype(np.float32)), o3d.core.Tensor(triangles.astype(np.uint32)))
    return ours, theirs


@pytest.mark.parametrize("ordered", [False, True])
def test_matches_open3d_on_the_same_mesh_and_rays(ordered):
    v, f = primitives.merge(
        [
            primitives.sphere(1.5, 4),
            (primitives.box((1.0, 2.0, 0.5))[0] + [3, 0, 0], primitives.box((1.0, 2.0, 0.5))[1]),
        ]
    )
    ours, theirs = _both(v, f)
    rng = np.random.default_rng(5)
    n = 20000
    if ordered:  # a spinning scan from one point
        az = np.tile(np.linspace(-np.pi, np.pi, 1000, endpoint=False), 20)
        el = np.repeat(np.linspace(-0.5, 0.5, 20), 1000)
        o = np.tile([0.2, -3.0, 0.1], (n, 1))
        d = np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    else:
        o = rng.uniform(-4, 4, (n, 3))
        d = rng.normal(size=(n, 3))
    rays = np.column_stack([o, d]).astype(np.float32)
    a = ours.cast_rays(rays)
    b = {k: x.numpy() for k, x in theirs.cast_rays(o3d.core.Tensor(rays)).items()}
    hit_a, hit_b = np.isfinite(a["t_hit"]), np.isfinite(b["t_hit"])
    np.testing.assert_array_equal(hit_a, hit_b)
    assert 0.05 < hit_a.mean() < 1.0
    np.testing.assert_allclose(a["t_hit"][hit_a], b["t_hit"][hit_a], atol=1e-4)
    np.testing.assert_array_equal(a["geometry_ids"], b["geometry_ids"])
    same_prim = a["primitive_ids"] == b["primitive_ids"]
    assert same_prim.mean() > 0.999  # only rays through shared edges may pick the other triangle
    np.testing.assert_allclose(a["normals"][same_prim], b["primitive_normals"][same_prim], atol=1e-5)


def test_open3d_agreement_on_a_builtin_world():
    w = cufund.worlds.load("imav2025_tunnel")
    v = np.vstack([o.vertices for o in w.objects])
    offsets = np.cumsum([0] + [len(o.vertices) for o in w.objects[:-1]])
    f = np.vstack([o.triangles + off for o, off in zip(w.objects, offsets, strict=True)])
    ours, theirs = _both(v, f)
    rng = np.random.default_rng(9)
    rays = np.column_stack([np.tile([-1.0, 0.0, 0.55], (10000, 1)), rng.normal(size=(10000, 3))]).astype(np.float32)
    a = ours.cast_rays(rays)["t_hit"]
    b = theirs.cast_rays(o3d.core.Tensor(rays))["t_hit"].numpy()
    np.testing.assert_array_equal(np.isfinite(a), np.isfinite(b))
    np.testing.assert_allclose(a, b, atol=1e-4)


@pytest.mark.parametrize(
    "vertices, triangles, message",
    [
        (np.zeros((3, 2)), [[0, 1, 2]], r"vertices must have shape \(V, 3\), got \(3, 2\)"),
        (np.zeros((3, 3)), np.zeros((0, 3), int), r"triangles must hold at least one triangle"),
        (np.zeros((3, 3)), [[0, 1, 3]], r"triangle 0 references a vertex index >= V"),
        (np.zeros((3, 3)), [[0, 1, -1]], r"triangles must hold vertex indices in \[0, V\), got -1"),
        (np.zeros((3, 3)), np.zeros((1, 3)), r"triangles must have an integer dtype, got float64"),
        (np.array([[0, 0, 0], [1, 0, np.nan], [0, 1, 0]]), [[0, 1, 2]], r"vertices must be finite.*vertex 1"),
        ("abc", [[0, 1, 2]], r"vertices must have a real numeric dtype"),
    ],
)
def test_bad_meshes_raise_value_error_naming_the_field(vertices, triangles, message):
    scene = RaycastScene()
    with pytest.raises(ValueError, match=message):
        scene.add_triangles(vertices, triangles)
    assert scene.num_geometries == 0


def test_bad_rays_raise_value_error_naming_the_ray():
    scene = _scene(primitives.box((1.0, 1.0, 1.0)))
    with pytest.raises(ValueError, match=r"rays must have shape \(N, 6\), got \(10, 3\)"):
        scene.cast_rays(np.zeros((10, 3), np.float32))
    rays = np.tile(np.array([0, 0, 0, 1, 0, 0], np.float32), (5, 1))
    rays[3, 4] = np.nan
    with pytest.raises(ValueError, match=r"rays must be finite, got a NaN or inf in ray 3"):
        scene.cast_rays(rays)
    rays[3] = 0
    with pytest.raises(ValueError, match=r"non-zero directions.*ray 3"):
        scene.cast_rays(rays)
    with pytest.raises(ValueError, match=r"nthreads must be >= 0"):
        scene.cast_rays(np.zeros((0, 6), np.float32), nthreads=-1)


def test_float64_rays_are_converted_and_empty_input_is_fine():
    scene = _scene(primitives.box((2.0, 2.0, 2.0)))
    out = scene.cast_rays(np.array([[0, 0, 0, 0, 0, 1.0]]))
    assert out["t_hit"].dtype == np.float32 and out["t_hit"][0] == pytest.approx(1.0)
    assert scene.cast_rays(np.zeros((0, 6), np.float32))["t_hit"].shape == (0,)


def test_degenerate_triangles_are_skipped_and_an_empty_scene_misses():
    v = np.array([[1.0, -1, -1], [1, 1, -1], [1, 1, -1]])
    scene = _scene((v, np.array([[0, 1, 2]])))
    out = scene.cast_rays(np.array([[0, 0, 0, 1, 0, 0]], np.float32))
    assert np.isinf(out["t_hit"][0])
    assert np.isinf(RaycastScene().cast_rays(np.array([[0, 0, 0, 1, 0, 0]], np.float32))["t_hit"][0])


def test_tiled_packets_on_a_large_scene_agree_with_single_rays():
    v, f = primitives.sphere(3.0, subdivisions=6)  # 81920 triangles: coherent rays get tiled
    scene = _scene((v, f))
    az = np.repeat(np.linspace(0, 2 * np.pi, 700, endpoint=False), 64)
    el = np.tile(np.linspace(-0.6, 0.6, 64), 700)
    d = np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    rays = np.column_stack([np.tile([0.3, -0.2, 0.1], (len(d), 1)), d]).astype(np.float32)
    a = scene.cast_rays(rays)  # auto: tiled packets
    b = scene.cast_rays(rays, coherent=False)
    np.testing.assert_array_equal(a["primitive_ids"], b["primitive_ids"])
    np.testing.assert_allclose(a["t_hit"], b["t_hit"], rtol=1e-6)
    np.testing.assert_allclose(a["normals"], b["normals"], atol=1e-6)
