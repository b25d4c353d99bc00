"""cufund._core.odometry against independent references: GTSAM's preintegration, ray casting of the static
scene, brute-force grouping and Open3D's KD-tree."""

import gtsam
import numpy as np
import open3d as o3d
import pytest
from scipy.spatial.transform import Rotation

from cufund import _core
from cufund.geometry import Transform
from cufund.sensors.lidar import Lidar, mid360_params
from cufund.sensors.patterns import Mid360Pattern
from cufund.worlds import load

odo = _core.odometry
G = 9.80665


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_imu_propagation_equals_gtsam_predict(seed):
    rng = np.random.default_rng(seed)
    n = 150
    dt = rng.uniform(0.002, 0.008, n)
    acc = rng.normal(0.0, 4.0, (n, 3)) + [0.0, 0.0, G]
    gyr = rng.normal(0.0, 1.5, (n, 3))
    ba, bg = rng.normal(0.0, 0.2, 3), rng.normal(0.0, 0.05, 3)
    R0 = Rotation.random(random_state=seed).as_matrix()
    p0, v0 = rng.normal(size=3), rng.normal(size=3)
    params = gtsam.PreintegrationCombinedParams.MakeSharedU(G)
    bias = gtsam.imuBias.ConstantBias(ba, bg)
    pim = gtsam.PreintegratedCombinedMeasurements(params, bias)
    q0 = Rotation.from_matrix(R0).as_quat()[[3, 0, 1, 2]]
    states, rates = odo.imu_propagate(p0, v0, q0, ba, bg, [0.0, 0.0, -G], dt, acc, gyr)
    assert states.shape == (n + 1, 10) and rates.shape == (n, 6)
    for k in range(n):
        pim.integrateMeasurement(acc[k], gyr[k], dt[k])
        if k % 37 == 36 or k == n - 1:
            ref = pim.predict(gtsam.NavState(gtsam.Rot3(R0), p0, v0), bias)
            s = states[k + 1]
            R = Rotation.from_quat(s[[7, 8, 9, 6]]).as_matrix()
            np.testing.assert_allclose(s[:3], ref.position(), atol=1e-9)
            np.testing.assert_allclose(s[3:6], ref.velocity(), atol=1e-9)
            np.testing.assert_allclose(R, ref.pose().rotation().matrix(), atol=1e-9)


def _level_yaw_motion(p0, v, yaw_rate):
    """Body at constant velocity and yaw rate, level: an IMU at the body reads (0, 0, g) and (0, 0, yaw_rate)."""

    def pose(t):
        return p0 + v * t, np.r_[np.cos(yaw_rate * t / 2), 0.0, 0.0, np.sin(yaw_rate * t / 2)]

    return pose


def test_deskewed_moving_scan_matches_the_scene_seen_at_rest():
    world = load("imav2025_tunnel")
    p0, v, yaw_rate = np.array([-3.0, -1.5, 1.5]), np.array([1.5, 0.4, 0.1]), 1.0
    pose = _level_yaw_motion(p0, v, yaw_rate)
    T_BL = Transform(
        t=(0.05, 0.02, 0.06), q=tuple(Rotation.from_euler("xyz", [0.1, 0.2, -0.3]).as_quat()[[3, 0, 1, 2]])
    )
    sigma = 0.02
    lidar = Lidar(Mid360Pattern(point_rate=50_000), mid360_params(range_noise_std=sigma, seed=3), T_BL)
    cloud = lidar.scan(world, pose, 0.0)
    t_pts = cloud.t + cloud.dt if hasattr(cloud, "dt") else cloud.t  # the PointCloud shape is changing
    t_end = 0.1
    n_imu = 24
    knot_t = -0.01 + 0.005 * np.arange(n_imu + 1)
    p_start, q_start = pose(knot_t[0])
    states, rates = odo.imu_propagate(
        p_start,
        v,
        q_start,
        np.zeros(3),
        np.zeros(3),
        [0, 0, -G],
        np.full(n_imu, 0.005),
        np.tile([0.0, 0.0, G], (n_imu, 1)),
        np.tile([0.0, 0.0, yaw_rate], (n_imu, 1)),
    )
    M_BL = np.eye(4)
    M_BL[:3, :3] = Rotation.from_quat(np.r_[T_BL.q[1:], T_BL.q[0]]).as_matrix()
    M_BL[:3, 3] = T_BL.t
    out = odo.deskew(cloud.points_L, t_pts, knot_t, states, rates, t_end, np.eye(4), M_BL)
    # Cast each deskewed point's ray from the LiDAR at rest at t_end: the range must agree within the noise.
    p_e, q_e = pose(t_end)
    R_WB = Rotation.from_quat(np.r_[q_e[1:], q_e[0]]).as_matrix()
    R_WL, p_WL = R_WB @ M_BL[:3, :3], p_e + R_WB @ M_BL[:3, 3]

    def range_errors(points_L):
        r = np.linalg.norm(points_L, axis=1)
        d_W = (points_L / r[:, None]) @ R_WL.T
        rays = np.hstack([np.tile(p_WL, (len(r), 1)), d_W]).astype(np.float32)
        hit = world.raycast_scene.cast_rays(rays)["t_hit"]
        return r - hit

    err = range_errors(out)
    raw = range_errors(np.asarray(cloud.points_L, dtype=float))
    # Gaussian range noise: median |error| = 0.674 sigma. (A few points hidden from the end pose by the
    # frames hit something else: they are what the tail bound allows.)
    assert np.median(np.abs(err)) < 1.1 * 0.674 * sigma
    assert np.mean(np.abs(err) < 4 * sigma) > 0.995
    assert np.median(np.abs(raw)) > 2 * np.median(np.abs(err))  # the motion did distort the raw scan
    assert np.mean(np.abs(raw) < 4 * sigma) < 0.9


def test_prepare_scan_equals_deskew_range_filter_and_two_downsamples():
    rng = np.random.default_rng(8)
    n = 5000
    pts = rng.uniform(-6, 6, (n, 3)).astype(np.float32)
    pts[:40] *= 0.01  # returns from the airframe, dropped by min_range
    t = np.sort(rng.uniform(0.0, 0.1, n))
    n_imu = 22
    knot_t = -0.005 + 0.005 * np.arange(n_imu + 1)
    states, rates = odo.imu_propagate(
        [1.0, 2.0, 1.5],
        [0.8, -0.3, 0.1],
        np.array([0.9, 0.1, -0.2, 0.3]) / np.sqrt(0.95),
        np.zeros(3),
        np.zeros(3),
        [0, 0, -G],
        np.full(n_imu, 0.005),
        rng.normal([0, 0, G], 0.5, (n_imu, 3)),
        rng.normal(0, 0.4, (n_imu, 3)),
    )
    M_BI, M_BL = np.eye(4), np.eye(4)
    M_BI[:3, :3] = Rotation.from_rotvec([0.02, -0.01, 0.3]).as_matrix()
    M_BI[:3, 3] = [0.01, 0.02, -0.01]
    M_BL[:3, :3] = Rotation.from_rotvec([0.1, 0.2, -0.3]).as_matrix()
    M_BL[:3, 3] = [0.05, 0.0, 0.08]
    ins_I, scan_I = odo.prepare_scan(pts, t, knot_t, states, rates, 0.1, M_BI, M_BL, 0.3, 0.05, 0.3)
    d = odo.deskew(pts, t, knot_t, states, rates, 0.1, M_BI, M_BL)
    d = d[np.linalg.norm(d, axis=1) >= 0.3]
    ins_L = odo.voxel_downsample(d, 0.05)
    scan_L = odo.voxel_downsample(ins_L, 0.3)
    T_IL = np.linalg.inv(M_BI) @ M_BL
    assert 100 < len(scan_I) < len(ins_I) < n - 40
    np.testing.assert_allclose(ins_I, ins_L @ T_IL[:3, :3].T + T_IL[:3, 3], atol=1e-12)
    np.testing.assert_allclose(scan_I, scan_L @ T_IL[:3, :3].T + T_IL[:3, 3], atol=1e-12)
    with pytest.raises(ValueError, match="scan_voxel"):
        odo.prepare_scan(pts, t, knot_t, states, rates, 0.1, M_BI, M_BL, 0.3, 0.05, 0.0)
    with pytest.raises(ValueError, match="min_range"):
        odo.prepare_scan(pts, t, knot_t, states, rates, 0.1, M_BI, M_BL, np.nan, 0.05, 0.3)
    with pytest.raises(ValueError, match="T_BL"):
        odo.prepare_scan(pts, t, knot_t, states, rates, 0.1, M_BI, np.diag([1.0, 1, -1, 1]), 0.3, 0.05, 0.3)


def test_voxel_downsample_equals_numpy_grouping():
    rng = np.random.default_rng(5)
    pts = rng.uniform(-2, 2, (3000, 3))
    out = odo.voxel_downsample(pts, 0.3)
    keys = np.floor(pts / 0.3).astype(int)
    uniq, first, inv = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inv = inv.reshape(-1)
    ref = np.zeros((len(uniq), 3))
    np.add.at(ref, inv, pts)
    ref /= np.bincount(inv)[:, None]
    np.testing.assert_allclose(out, ref[np.argsort(first)], atol=1e-12)  # in first-seen order


def test_knn_and_normals_match_open3d():
    rng = np.random.default_rng(6)
    # A box room: six noisy walls.
    u = rng.uniform(0, 4, (30000, 2))
    walls = []
    for axis in range(3):
        for c in (0.0, 4.0):
            w = np.insert(u[:5000], axis, c, axis=1)
            walls.append(w)
    pts = np.vstack(walls) + rng.normal(0, 0.005, (30000, 3))
    vmap = odo.VoxelMap(voxel_size=0.5, max_points_per_voxel=30, min_point_distance=0.02)
    vmap.insert(pts, [2.0, 2.0, 2.0])
    stored = vmap.points()
    assert len(stored) == len(vmap) > 1000
    queries = np.vstack([w[:100] for w in walls]) + rng.normal(0, 0.05, (600, 3))
    nb, d2 = vmap.knn(queries, 8, 0.5)
    tree = o3d.geometry.KDTreeFlann(o3d.geometry.PointCloud(o3d.utility.Vector3dVector(stored)))
    for i, q in enumerate(queries):
        _, idx, dist2 = tree.search_hybrid_vector_3d(q, 0.5, 8)
        found = np.isfinite(d2[i])
        np.testing.assert_allclose(d2[i][found], np.asarray(dist2), rtol=1e-9, atol=1e-12)
        assert found.sum() == len(idx)
    # Normals: the smallest principal axis of the 5 nearest neighbours (Open3D's search, numpy PCA).
    terms = vmap.point_to_plane(
        queries, np.eye(3), np.zeros(3), neighbours=5, max_neighbour_distance=0.5, max_plane_rms=0.05, max_residual=0.3
    )
    valid = terms["valid"]
    assert valid.mean() > 0.9
    for i in np.nonzero(valid)[0][::7]:
        _, idx, _ = tree.search_knn_vector_3d(queries[i], 5)
        nbrs = stored[np.asarray(idx)]
        c = nbrs.mean(axis=0)
        n_ref = np.linalg.eigh(np.cov((nbrs - c).T, bias=True))[1][:, 0]
        assert abs(abs(np.dot(n_ref, terms["normal"][i])) - 1.0) < 1e-9
        assert abs(abs(terms["residual"][i]) - abs(np.dot(n_ref, queries[i] - c))) < 1e-9


def test_bad_input_raises_value_error_naming_the_argument():
    knot_t = np.array([0.0, 0.1])
    states = np.tile([0, 0, 0, 0, 0, 0, 1.0, 0, 0, 0], (2, 1))
    rates = np.zeros((1, 6))
    pts = np.ones((4, 3), np.float32)
    t = np.zeros(4)
    sheared = np.eye(4)
    sheared[0, 1] = 0.3
    with pytest.raises(ValueError, match="T_BI"):
        odo.deskew(pts, t, knot_t, states, rates, 0.1, sheared, np.eye(4))
    mirrored = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(ValueError, match="T_BL"):
        odo.deskew(pts, t, knot_t, states, rates, 0.1, np.eye(4), mirrored)
    bad = pts.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="points_L"):
        odo.deskew(bad, t, knot_t, states, rates, 0.1, np.eye(4), np.eye(4))
    with pytest.raises(ValueError, match="knot_t"):
        odo.deskew(pts, t, knot_t[::-1], states, rates, 0.1, np.eye(4), np.eye(4))
    with pytest.raises(ValueError, match="q_WI"):
        odo.imu_propagate(
            np.zeros(3),
            np.zeros(3),
            [1.0, 1.0, 0, 0],
            np.zeros(3),
            np.zeros(3),
            [0, 0, -G],
            [0.01],
            [[0, 0, G]],
            [[0, 0, 0]],
        )
    with pytest.raises(ValueError, match="dt"):
        odo.imu_propagate(
            np.zeros(3),
            np.zeros(3),
            [1.0, 0, 0, 0],
            np.zeros(3),
            np.zeros(3),
            [0, 0, -G],
            [0.0],
            [[0, 0, G]],
            [[0, 0, 0]],
        )
    vmap = odo.VoxelMap()
    with pytest.raises(ValueError, match="R_WI"):
        vmap.point_to_plane(np.zeros((3, 3)), 2 * np.eye(3), np.zeros(3))
    with pytest.raises(ValueError, match="robust"):
        vmap.point_to_plane(np.zeros((3, 3)), np.eye(3), np.zeros(3), robust="tukey")
    with pytest.raises(ValueError, match="points_W"):
        vmap.insert(np.full((2, 3), np.inf), np.zeros(3))


def test_bad_arrays_raise_value_error_naming_the_argument():
    """Wrong dtypes, shapes and objects numpy cannot convert (the odometry bindings read arrays through the checked
    helpers of pybind_common.h, not array::ensure, which dropped the conversion error)."""
    knot_t = np.array([0.0, 0.1])
    states = np.tile([0, 0, 0, 0, 0, 0, 1.0, 0, 0, 0], (2, 1))
    rates = np.zeros((1, 6))
    t = np.zeros(4)
    with pytest.raises(ValueError, match="points_L must have a real numeric dtype, got <U1"):
        odo.deskew(np.full((4, 3), "a"), t, knot_t, states, rates, 0.1, np.eye(4), np.eye(4))
    with pytest.raises(ValueError, match=r"points_L must have shape \(N, 3\), got \(4, 2\)"):
        odo.deskew(np.ones((4, 2)), t, knot_t, states, rates, 0.1, np.eye(4), np.eye(4))
    with pytest.raises(ValueError, match="points_L must be an array, got list"):
        odo.deskew([[0, 0, 0], [1, 1]], t, knot_t, states, rates, 0.1, np.eye(4), np.eye(4))
    points_I = np.zeros((3, 3))
    planes = np.tile([0, 0, 1.0, 0], (3, 1))
    with pytest.raises(ValueError, match=r"valid must be a bool array of shape \(3,\), got float64 \(3,\)"):
        odo.plane_terms(points_I, planes, np.ones(3), np.eye(3), np.zeros(3))
    with pytest.raises(ValueError, match="valid must be an array, got list"):
        odo.plane_terms(points_I, planes, [[True], [True, False]], np.eye(3), np.zeros(3))
    with pytest.raises(ValueError, match="points_I must be an array, got list"):
        odo.plane_terms([[0, 0, 0], [1, 1]], planes, np.ones(3, bool), np.eye(3), np.zeros(3))
