"""The analytic prism depth caster (cpp/envs/prism_cast.h) against Embree's RaycastScene on the same meshes, and
disagreements against an independent double-precision ray/triangle cast (Moeller-Trumbore in numpy)."""

from __future__ import annotations

import numpy as np
import pytest

from cufund import _core
from cufund.envs.forest_avoid import ForestAvoidEnv, ForestParams
from cufund.envs.observation_sensors import BatchRangeSensor, DepthCameraSpec, prism_scene, sensor_poses
from cufund.geometry import quat_to_matrix
from cufund.worlds.world import World


def _poses(world: World, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """n seeded poses over and around the forest, every attitude, none inside a trunk's box."""
    rng = np.random.default_rng(seed)
    boxes = [(o.vertices.min(0) - 0.01, o.vertices.max(0) + 0.01) for o in world.objects if o.label == "tree"]
    p: list[np.ndarray] = []
    while len(p) < n:
        x = np.array([rng.uniform(-14, 14), rng.uniform(-14, 14), rng.uniform(0.05, 12.0)])
        if not any(np.all(x >= lo) and np.all(x <= hi) for lo, hi in boxes):
            p.append(x)
    q = rng.normal(size=(n, 4))
    return np.array(p), q / np.linalg.norm(q, axis=1, keepdims=True)


def _reference(world: World, o: np.ndarray, d: np.ndarray) -> float:
    """The first hit's distance along d of o + t d over every triangle of the world, in float64 (inf: none)."""
    best = np.inf
    for ob in world.objects:
        v = np.asarray(ob.vertices, dtype=np.float32).astype(np.float64)
        a, b, c = (v[ob.triangles[:, k]] for k in range(3))
        e1, e2 = b - a, c - a
        h = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, h)
        with np.errstate(divide="ignore", invalid="ignore"):
            f = 1.0 / det
            s = o - a
            u = f * np.einsum("ij,ij->i", s, h)
            qv = np.cross(s, e1)
            w = f * (qv @ d)
            t = f * np.einsum("ij,ij->i", e2, qv)
        ok = (u >= 0) & (w >= 0) & (u + w <= 1) & (t > 0)
        if ok.any():
            best = min(best, float(t[ok].min()))
    return best


@pytest.fixture(scope="module")
def forest() -> World:
    return ForestParams().build()


def test_forest_is_a_prism_scene_and_other_worlds_fall_back(forest: World) -> None:
    scene = prism_scene(forest)
    assert scene is not None and scene.num_prisms == 80 and scene.num_rects == 1
    w = World("ball")
    w.add_plane((10.0, 10.0), (0.0, 0.0, 0.0), label="ground")
    w.add_sphere(0.5, (2.0, 0.0, 1.0), label="ball")
    assert prism_scene(w) is None  # not trunks and ground: Embree casts
    tilted = World("tilted")
    tilted.add_box((1.0, 1.0, 1.0), (2.0, 0.0, 1.0), yaw=0.3, label="crate")  # a vertical convex prism too
    assert prism_scene(tilted) is not None and prism_scene(tilted).num_prisms == 1


def test_equals_embree_on_random_poses(forest: World) -> None:
    spec = DepthCameraSpec()
    embree = BatchRangeSensor(forest.raycast_scene, spec)
    analytic = BatchRangeSensor(forest.raycast_scene, spec, prisms=prism_scene(forest))
    p, q = _poses(forest, 400, seed=3)
    a, e = analytic.observe(p, q), embree.observe(p, q)
    hit_a, hit_e = a < spec.range_max, e < spec.range_max
    assert hit_e.mean() > 0.3 and (hit_e & (e > 1.0)).sum() > 10_000  # trunks and ground in view
    both = hit_a & hit_e
    close = np.abs(a - e) < 1e-4
    odd = np.argwhere((hit_a != hit_e) | (both & ~close))
    # The rest: rays grazing an edge, where one of the float casts leaks. The double-precision reference decides.
    assert len(odd) <= 1e-5 * a.size, f"{len(odd)} disagreements of {a.size}"
    d_S = spec.directions().astype(np.float64)
    for i, v, u in odd:
        ref = _reference(forest, p[i], np.asarray(quat_to_matrix(q[i])) @ d_S[v * spec.width + u])
        ref = ref if spec.range_min <= ref <= spec.range_max else spec.range_max
        assert abs(a[i, v, u] - ref) < 1e-3 * max(1.0, ref), (i, v, u, a[i, v, u], e[i, v, u], ref)


def test_range_model_and_noise_streams_are_batch_casts(forest: World) -> None:
    spec = DepthCameraSpec(width=32, height=24, fov_deg=70.0, range_max=8.0, range_noise_std=0.01, dropout=0.1)
    embree = BatchRangeSensor(forest.raycast_scene, spec, seed=5)
    analytic = BatchRangeSensor(forest.raycast_scene, spec, seed=5, prisms=prism_scene(forest))
    p, q = _poses(forest, 50, seed=4)
    a, e = analytic.observe(p, q, frame=7), embree.observe(p, q, frame=7)
    assert a.shape == (50, 24, 32)
    np.testing.assert_array_equal(a == spec.range_max, e == spec.range_max)  # dropout draws, range cut
    np.testing.assert_allclose(a, e, atol=1e-4)
    assert not np.array_equal(a, analytic.observe(p, q, frame=8))  # a new frame, new draws


def test_forest_avoid_casts_analytically_and_lidar_stays_on_embree() -> None:
    env = ForestAvoidEnv(4)
    assert env.sensor.prisms is not None
    obs, _ = env.reset(seed=0)
    ref = BatchRangeSensor(env.world.raycast_scene, env.sensor.spec).observe(
        np.asarray(env.batch.p), np.asarray(env.batch.q)
    )
    np.testing.assert_allclose(obs["depth"][:, 0], ref, atol=1e-4)
    # and it is the analytic caster's image bit for bit (Embree's last bits differ: the routing is what is checked)
    s = env.sensor.spec
    p_WS, q_WS = sensor_poses(np.asarray(env.batch.p), np.asarray(env.batch.q), s.p_BS, s.q_BS)
    direct = _core.envs.prism_depth_cast(
        prism_scene(env.world),
        s.directions(),
        p_WS,
        q_WS,
        width=s.width,
        height=s.height,
        focal=s.focal_px,
        range_min=s.range_min,
        range_max=s.range_max,
        miss_value=s.range_max,
    )
    np.testing.assert_array_equal(obs["depth"][:, 0].reshape(4, -1), direct)
    assert not np.array_equal(obs["depth"][:, 0], ref)
    assert ForestAvoidEnv(2, sensor="lidar").sensor.prisms is None


def test_bad_input_is_named() -> None:
    with pytest.raises(ValueError, match="planes must have shape"):
        _core.envs.PrismScene(np.zeros((2, 2)), np.array([0, 2]), np.zeros((1, 6)), np.zeros((0, 5)))
    with pytest.raises(ValueError, match="prism 0"):
        _core.envs.PrismScene(np.array([[0.0, 0.0, 1.0]]), np.array([0, 1]), np.zeros((1, 6)), np.zeros((0, 5)))
    with pytest.raises(ValueError, match="rect 0"):
        _core.envs.PrismScene(np.zeros((0, 3)), np.array([0]), np.zeros((0, 6)), np.array([[0.0, 1.0, -1.0, 0.0, 1.0]]))
    scene = prism_scene(ForestParams().build())
    spec = DepthCameraSpec(width=4, height=4)
    with pytest.raises(ValueError, match="d_S must have shape"):
        _core.envs.prism_depth_cast(
            scene, np.ones((3, 3), np.float32), np.zeros((1, 3)), [[1.0, 0, 0, 0]], width=4, height=4, focal=2.0
        )
    # The caster culls by the pixels (width, height, focal) map a prism to: other rays are refused, not cast.
    other = DepthCameraSpec(width=4, height=4, fov_deg=60.0)
    with pytest.raises(ValueError, match="d_S must be the rays"):
        _core.envs.prism_depth_cast(
            scene, other.directions(), np.zeros((1, 3)), [[1.0, 0, 0, 0]], width=4, height=4, focal=spec.focal_px
        )
    wide = DepthCameraSpec(width=8, height=2)
    with pytest.raises(ValueError, match="d_S must be the rays"):
        _core.envs.prism_depth_cast(
            scene, wide.directions(), np.zeros((1, 3)), [[1.0, 0, 0, 0]], width=2, height=8, focal=wide.focal_px
        )
    with pytest.raises(ValueError, match="d_S must have a real numeric dtype"):
        _core.envs.prism_depth_cast(
            scene, spec.directions().astype(str), np.zeros((1, 3)), [[1.0, 0, 0, 0]], width=4, height=4, focal=2.0
        )
    # batch_cast's bounds on the range model: an infinite noise or range_min is refused, not cast
    for bad in ({"noise_std": np.inf}, {"noise_per_m": np.inf}, {"range_min": np.inf}):
        with pytest.raises(ValueError, match="finite"):
            _core.envs.prism_depth_cast(
                scene, spec.directions(), np.zeros((1, 3)), [[1.0, 0, 0, 0]], width=4, height=4, focal=2.0, **bad
            )
        with pytest.raises(ValueError, match="finite"):
            _core.lidar.batch_cast(
                ForestParams().build().raycast_scene, spec.directions(), np.zeros((1, 3)), [[1.0, 0, 0, 0]], **bad
            )
    # ... read by the one parser both casters share: the same error, naming the argument
    named = [
        ({"dropout": 1.0}, ValueError, r"dropout must be in \[0, 1\)"),
        ({"range_min": 2.0, "range_max": 1.0}, ValueError, "range_max must be >= range_min"),
        ({"seed": -1}, ValueError, "seed must be an integer in"),
        ({"frame": 1.5}, TypeError, "frame must be an integer"),
        ({"noise_std": "0.1"}, TypeError, "noise_std must be a real number"),
    ]
    for bad, error, match in named:
        with pytest.raises(error, match=match):
            _core.envs.prism_depth_cast(
                scene, spec.directions(), np.zeros((1, 3)), [[1.0, 0, 0, 0]], width=4, height=4, focal=2.0, **bad
            )
        with pytest.raises(error, match=match):
            _core.lidar.batch_cast(
                ForestParams().build().raycast_scene, spec.directions(), np.zeros((1, 3)), [[1.0, 0, 0, 0]], **bad
            )
    with pytest.raises(ValueError, match="item 0"):
        _core.envs.prism_depth_cast(
            scene, spec.directions(), [[np.nan, 0, 0]], [[1.0, 0, 0, 0]], width=4, height=4, focal=2.0
        )
