"""Batched depth and LiDAR casts (cufund._core.lidar.batch_cast, cufund.envs.observation_sensors) against
per-vehicle RaycastScene casts, Open3D's ray caster and analytic depths."""

from __future__ import annotations

import numpy as np
import open3d as o3d
import pytest
from scipy.spatial.transform import Rotation

from cufund._core import lidar
from cufund.core.config import ConfigError
from cufund.envs.observation_sensors import (
    BatchRangeSensor,
    DepthCameraSpec,
    LidarSpec,
    VehicleBoxes,
    sensor_poses,
)
from cufund.sensors.lidar import mid360_params
from cufund.worlds import World
from cufund.worlds.builtin import forest


def _wxyz(r: Rotation) -> np.ndarray:
    return np.roll(r.as_quat(), 1, axis=-1)


@pytest.fixture(scope="module")
def forest_scene() -> lidar.RaycastScene:
    return forest(seed=3, n_trees=60, size=20.0).raycast_scene


def _poses(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    p = np.c_[rng.uniform(-8, 8, (n, 2)), rng.uniform(0.3, 3.0, n)]
    q = _wxyz(Rotation.random(n, random_state=seed))
    return p, q


def _reference(scene: lidar.RaycastScene, rays: np.ndarray, lo: float, hi: float, coherent: bool) -> np.ndarray:
    """Per-vehicle casts through the existing RaycastScene API, with the documented range rule."""
    out = []
    for r in rays:
        t = scene.cast_rays(r, coherent=coherent)["t_hit"]
        out.append(np.where((t >= np.float32(lo)) & (t <= np.float32(hi)), t, np.float32(hi)))
    return np.stack(out)


def test_rays_are_the_poses_rotated_directions() -> None:
    p, q = _poses(7, 1)
    d = DepthCameraSpec(width=8, height=6).directions()
    rays = lidar.batch_rays(d, p, q)
    assert rays.shape == (7, 48, 6) and rays.dtype == np.float32
    R = Rotation.from_quat(np.roll(q, -1, axis=1)).as_matrix()
    np.testing.assert_array_equal(rays[:, :, :3], np.broadcast_to(p[:, None, :].astype(np.float32), (7, 48, 3)))
    np.testing.assert_allclose(rays[:, :, 3:], np.einsum("nij,rj->nri", R, d.astype(np.float64)), rtol=0, atol=1e-6)


@pytest.mark.parametrize(
    "spec",
    [
        DepthCameraSpec(width=64, height=64, fov_deg=90.0, range_max=15.0, p_BS=(0.05, 0.0, 0.02)),
        LidarSpec(pattern="mid360", stride=7, range_max=12.0),
        LidarSpec(pattern="vlp16", frame=3, stride=5, range_min=0.5),
    ],
    ids=["depth64", "mid360", "vlp16"],
)
def test_batch_equals_per_vehicle_raycastscene_casts(forest_scene: lidar.RaycastScene, spec: object) -> None:
    p_WB, q_WB = _poses(9, 2)
    sensor = BatchRangeSensor(forest_scene, spec)  # type: ignore[arg-type]
    got = sensor.observe(p_WB, q_WB).reshape(9, -1)
    p_WS, q_WS = sensor_poses(p_WB, q_WB, spec.p_BS, spec.q_BS)  # type: ignore[attr-defined]
    rays = lidar.batch_rays(sensor.d_S, p_WS, q_WS)
    lo, hi = spec.range_min, spec.range_max  # type: ignore[attr-defined]
    # bit for bit against the same rays in coherent packets (what batch_cast promises) ...
    np.testing.assert_array_equal(got, _reference(forest_scene, rays, lo, hi, coherent=True))
    # ... and to float eps against single rays (Embree's packets may differ in the last bits)
    np.testing.assert_allclose(got, _reference(forest_scene, rays, lo, hi, coherent=False), rtol=1e-5, atol=1e-5)
    assert np.mean(got < hi) > 0.2  # the forest is in the picture: ground and trunks
    # one thread or all: the same numbers
    np.testing.assert_array_equal(
        got, BatchRangeSensor(forest_scene, spec, nthreads=1).observe(p_WB, q_WB).reshape(9, -1)
    )  # type: ignore[arg-type]


def test_depth_is_the_distance_along_the_optical_axis() -> None:
    world = World()
    world.add_box((0.2, 400.0, 400.0), (5.1, 0.0, 0.0))  # a wall whose face is the plane x = 5
    spec = DepthCameraSpec(width=32, height=24, fov_deg=100.0, range_max=30.0)
    depth = BatchRangeSensor(world.raycast_scene, spec).observe([[0.0, 0.0, 0.0]], [[1.0, 0.0, 0.0, 0.0]])
    assert depth.shape == (1, 24, 32)
    np.testing.assert_allclose(depth, 5.0, rtol=1e-6)
    # the camera yawed 30 deg left: pixel u (image right = body -y) looks along R_z(30) (1, -x_n, .), which meets
    # the plane x = 5 at depth 5 / (cos 30 + sin 30 x_n)
    yaw = np.radians(30.0)
    depth = BatchRangeSensor(world.raycast_scene, spec).observe([[0, 0, 0]], [[np.cos(yaw / 2), 0, 0, np.sin(yaw / 2)]])
    xn = (np.arange(32) + 0.5 - 16) / spec.focal_px
    expected = 5.0 / (np.cos(yaw) + np.sin(yaw) * xn)
    np.testing.assert_allclose(depth[0], np.broadcast_to(expected, (24, 32)), rtol=1e-5)
    # image orientation: a camera pitched down 45 deg sees the ground nearer in the bottom rows
    ground = World()
    ground.add_plane((100.0, 100.0), (0.0, 0.0, 0.0))
    pitch = np.radians(45.0)
    img = BatchRangeSensor(ground.raycast_scene, spec).observe(
        [[0, 0, 2.0]], [[np.cos(pitch / 2), 0, np.sin(pitch / 2), 0]]
    )[0]
    assert np.all(np.diff(img[:, 16]) < 0)
    np.testing.assert_allclose(img[12, :], img[12, 0], rtol=1e-5)  # a row is level


def test_each_sensor_sees_the_other_vehicles_boxes_like_open3d_sees_their_meshes() -> None:
    h = np.array([0.12, 0.08, 0.03])
    rng = np.random.default_rng(5)
    n = 4
    p = rng.uniform(-1.0, 1.0, (n, 3))
    q = _wxyz(Rotation.random(n, random_state=7))
    spec = DepthCameraSpec(width=48, height=48, fov_deg=120.0, range_max=10.0)
    d = spec.directions()
    got = lidar.batch_cast(
        lidar.RaycastScene(),
        d,
        p,
        q,
        box_p_W=p,
        box_q_W=q,
        box_half_extents=np.broadcast_to(h, (n, 3)),
        box_owner=np.arange(n),
        range_max=10.0,
        miss_value=np.inf,
    )
    rays = lidar.batch_rays(d, p, q)
    R = Rotation.from_quat(np.roll(q, -1, axis=1)).as_matrix()
    for i in range(n):
        o3 = o3d.t.geometry.RaycastingScene()
        for j in range(n):
            if j == i:
                continue
            m = o3d.geometry.TriangleMesh.create_box(*(2 * h))
            m.translate(-h)
            m.rotate(R[j], center=(0, 0, 0))
            m.translate(p[j])
            o3.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(m))
        ref = o3.cast_rays(o3d.core.Tensor(rays[i].astype(np.float32)))["t_hit"].numpy()
        ref = np.where(ref <= 10.0, ref, np.inf)
        assert np.array_equal(np.isinf(got[i]), np.isinf(ref)) or np.mean(np.isinf(got[i]) != np.isinf(ref)) < 2e-3
        both = np.isfinite(got[i]) & np.isfinite(ref)
        np.testing.assert_allclose(got[i][both], ref[both], rtol=1e-4, atol=1e-5)
    assert np.isfinite(got).any()


def test_an_agent_depth_sees_the_other_vehicle_and_not_itself() -> None:
    scene = World().raycast_scene  # nothing in the world
    spec = DepthCameraSpec(width=16, height=16, range_max=10.0)
    p = np.array([[0.0, 0.0, 1.0], [3.0, 0.0, 1.0]])
    q = np.array([[1.0, 0, 0, 0], [0.0, 0, 0, 1.0]])  # the second yawed 180 deg: they face each other
    seen = BatchRangeSensor(scene, spec, boxes=VehicleBoxes((0.1, 0.25, 0.25))).observe(p, q)
    blind = BatchRangeSensor(scene, spec).observe(p, q)
    assert np.all(blind == 10.0)
    # the centre pixels look at the other's face, a plane 3 - 0.1 m away along the axis
    np.testing.assert_allclose(seen[:, 7:9, 7:9], 2.9, rtol=1e-6)
    assert np.all(seen[:, 0, :] == 10.0)  # the top row passes over it


def test_noise_is_the_lidar_range_model_and_seeded() -> None:
    world = World()
    world.add_box((0.2, 200.0, 200.0), (10.1, 0.0, 0.0))
    spec = DepthCameraSpec(
        width=64, height=64, fov_deg=60.0, range_max=50.0, range_noise_std=0.02, range_noise_per_m=0.003, dropout=0.1
    )
    n = 16
    p, q = np.zeros((n, 3)), np.tile([1.0, 0, 0, 0], (n, 1))
    clean = BatchRangeSensor(world.raycast_scene, DepthCameraSpec(width=64, height=64, fov_deg=60.0, range_max=50.0))
    truth = clean.observe(p, q)
    a = BatchRangeSensor(world.raycast_scene, spec, seed=11).observe(p, q, frame=4)
    np.testing.assert_array_equal(a, BatchRangeSensor(world.raycast_scene, spec, seed=11, nthreads=1).observe(p, q, 4))
    assert not np.array_equal(a, BatchRangeSensor(world.raycast_scene, spec, seed=12).observe(p, q, 4))
    assert not np.array_equal(a, BatchRangeSensor(world.raycast_scene, spec, seed=11).observe(p, q, 5))
    assert not np.array_equal(a[0], a[1])  # vehicles draw from their own streams
    # vehicle i of a batch seeded s draws what a batch of one seeded s + i does
    one = BatchRangeSensor(world.raycast_scene, spec, seed=14).observe(p[:1], q[:1], frame=4)
    np.testing.assert_array_equal(a[3], one[0])
    dropped = a == 50.0
    assert abs(dropped.mean() - 0.1) < 0.01  # 65 536 draws: 4 sigma is 0.005
    z = (a[~dropped] - truth[~dropped]) / (0.02 + 0.003 * truth[~dropped])
    assert abs(z.mean()) < 0.02 and abs(z.std() - 1.0) < 0.02


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"p_WS": [[np.nan, 0, 0]]}, "p_WS and q_WS must be finite, sensor 0"),
        ({"q_WS": [[0.0, 0, 0, 0]]}, "q_WS must hold non-zero quaternions"),
        ({"d_S": [[0.0, 0, 0]]}, "d_S must hold non-zero directions, direction 0"),
        ({"q_WS": [[1.0, 0, 0]]}, r"q_WS must have shape \(1, 4\)"),
        ({"box_p_W": [[0.0, 0, 0]]}, "box_q_W and box_half_extents are required"),
        ({"dropout": 1.0}, r"dropout must be in \[0, 1\)"),
        (
            {"box_p_W": [[0.0, 0, 0]], "box_q_W": [[1.0, 0, 0, 0]], "box_half_extents": [[-1.0, 0, 0]]},
            "box 0: .* box_half_extents finite and >= 0",
        ),
        (
            {"box_p_W": [[0, 0, 0]], "box_q_W": [[1, 0, 0, 0]], "box_half_extents": [[1, 1, 1]], "box_owner": [3]},
            r"box_owner must hold box indices in \[-1, M\)",
        ),
    ],
)
def test_bad_input_names_the_field(kwargs: dict, match: str) -> None:
    args = {"d_S": [[1.0, 0, 0]], "p_WS": [[0.0, 0, 0]], "q_WS": [[1.0, 0, 0, 0]]}
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        lidar.batch_cast(lidar.RaycastScene(), **args)


def test_lidar_spec_takes_the_lidar_range_model() -> None:
    spec = LidarSpec.from_lidar_params(mid360_params(dropout=0.05), stride=10)
    assert (spec.range_min, spec.range_max, spec.range_noise_std, spec.dropout) == (0.1, 40.0, 0.02, 0.05)
    assert spec.pattern == "mid360" and spec.shape == (2000,)


def test_bad_specs_name_the_field() -> None:
    with pytest.raises(ConfigError, match="depth.width"):
        DepthCameraSpec(width=0)
    with pytest.raises(ConfigError, match="lidar.pattern must be one of"):
        LidarSpec(pattern="hdl64")
    with pytest.raises(ConfigError, match="depth.dropout"):
        DepthCameraSpec(dropout=1.0)
    with pytest.raises(ConfigError, match="q_BS"):
        DepthCameraSpec(q_BS=(0, 0, 0, 0))
