"""LiDAR scan patterns and the range model: FOV, points per frame, Livox coverage growth, per-point
timestamps and motion distortion, noise, dropout, intensity, determinism, bad input."""

from itertools import pairwise

import numpy as np
import pytest

import cufund
from cufund import sensors as L
from cufund.geometry import Transform, quat_to_matrix, yaw_quaternion


def covered_cells(pattern, frames, cell_deg=1.0):
    cells, counts = set(), []
    for k in range(frames):
        r = pattern.frame(k)
        a = np.floor(np.rad2deg(r.azimuth) / cell_deg).astype(int)
        e = np.floor(np.rad2deg(r.elevation) / cell_deg).astype(int)
        cells |= set(zip(a.tolist(), e.tolist(), strict=True))
        counts.append(len(cells))
    return counts


@pytest.mark.parametrize(
    "pattern, n, el_lo, el_hi, period",
    [
        (L.vlp16(), 16 * 1800, -15.0, 15.0, 0.1),
        (L.os1_64(), 64 * 1024, -16.6, 16.6, 0.1),
        (L.PlanarPattern(), 1081, 0.0, 0.0, 0.025),
        (L.mid360(), 20000, -7.0, 52.0, 0.1),
        (L.avia(), 24000, -38.6, 38.6, 0.1),
    ],
)
def test_patterns_fov_points_per_frame_and_timing(pattern, n, el_lo, el_hi, period):
    for k in (0, 3):
        r = pattern.frame(k)
        assert len(r.t) == n
        el = np.rad2deg(r.elevation)
        assert el.min() >= el_lo - 1e-6 and el.max() <= el_hi + 1e-6
        assert el.max() - el.min() >= 0.95 * (el_hi - el_lo)
        assert r.t.min() >= 0 and r.t.max() < period and np.all(np.diff(r.t) >= 0)
        np.testing.assert_allclose(np.linalg.norm(r.directions(), axis=1), 1.0)
    assert pattern.period == pytest.approx(period)


def test_planar_pattern_spans_270_degrees():
    az = np.rad2deg(L.PlanarPattern().frame(0).azimuth)
    assert az.min() == pytest.approx(-135.0) and az.max() == pytest.approx(135.0)


def test_mid360_coverage_grows_over_frames_while_a_spinning_lidar_repeats():
    mid = covered_cells(L.mid360(), 10)
    assert all(b > a for a, b in pairwise(mid[:5]))  # strictly growing early on
    full = 360 * 59
    assert mid[0] < 0.5 * full and mid[-1] > 0.95 * full
    vlp = covered_cells(L.vlp16(), 5)
    assert vlp == [vlp[0]] * 5
    r0, r1 = L.mid360().frame(0), L.mid360().frame(1)
    assert not np.allclose(r0.elevation, r1.elevation)  # non-repetitive


def test_avia_rosette_coverage_grows():
    c = covered_cells(L.avia(), 6, cell_deg=0.5)
    assert all(b > a for a, b in pairwise(c))
    assert c[-1] > 1.2 * c[0]


def test_csv_pattern_slices_frames_and_wraps(tmp_path):
    t = np.arange(300) * 1e-3  # 0.3 s of rows at 1 kHz
    az = np.linspace(-180, 180, 300, endpoint=False)
    zen = 90.0 - np.linspace(-10, 10, 300)
    path = tmp_path / "pattern.csv"
    np.savetxt(path, np.column_stack([t, az, zen]), delimiter=",", header="time,azimuth,zenith", comments="")
    p = L.CsvPattern(str(path), rate=10.0)
    f0, f1, f3 = p.frame(0), p.frame(1), p.frame(3)
    assert len(f0.t) == 100
    np.testing.assert_allclose(np.rad2deg(f0.azimuth), az[:100])
    np.testing.assert_allclose(np.rad2deg(f0.elevation), np.linspace(-10, 10, 300)[:100])
    np.testing.assert_allclose(np.rad2deg(f1.azimuth), az[100:200])
    np.testing.assert_allclose(f3.azimuth, f0.azimuth)  # the 0.3 s table wraps around
    bad = tmp_path / "bad.csv"
    bad.write_text("1,2\n3,4\n")
    with pytest.raises(ValueError, match="time, azimuth, zenith"):
        L.CsvPattern(str(bad))


def wall_world(x=10.0):
    w = cufund.World("wall")
    w.add_box((0.2, 200.0, 200.0), (x + 0.1, 0.0, 0.0), label="wall")
    return w


def static_pose(p=(0.0, 0.0, 0.0), q=(1.0, 0.0, 0.0, 0.0)):
    return lambda t: (np.array(p), np.array(q))


def test_ranges_to_a_wall_are_analytic_and_points_are_consistent():
    lid = L.Lidar(L.vlp16(), L.LidarParams(range_max=100.0))
    pc, truth = lid.scan_with_truth(wall_world(), static_pose((1.0, 0.5, 0.0)), 0.0)
    d = pc.points_L / np.linalg.norm(pc.points_L, axis=1, keepdims=True)
    np.testing.assert_allclose(pc.ranges, 9.0 / d[:, 0], rtol=1e-5)
    np.testing.assert_allclose(truth.points_W[:, 0], 10.0, atol=1e-4)
    assert len(truth.points_W) == len(pc) and truth.t == pc.t
    assert np.all(d[:, 0] > 0.09)  # returns only from the half facing the wall (range <= 100 m)


def test_motion_distortion_each_point_leaves_from_the_pose_at_its_own_time():
    v = 2.0
    x0 = 1.0
    lid = L.Lidar(L.mid360(), L.LidarParams(range_max=100.0))
    pc = lid.scan(wall_world(), lambda t: (np.array([x0 + v * (t - 5.0), 0.0, 0.0]), np.array([1.0, 0, 0, 0])), 5.0)
    # In the LiDAR frame at firing time the wall is at x = 10 - (x0 + v (t - 5)).
    assert pc.t == 5.0  # one stamp per frame (its start), a time offset per point
    np.testing.assert_allclose(pc.points_L[:, 0], 10.0 - (x0 + v * pc.dt), atol=2e-4)
    assert pc.dt.min() >= 0.0 and pc.dt.max() < 0.1
    assert np.ptp(pc.points_L[:, 0]) > 0.15  # 2 m/s over 0.1 s: the distortion is there to undistort


def test_rotating_sensor_with_mount_matches_the_exact_pose_per_point():
    rate = 3.0  # rad/s yaw
    T_BL = Transform((0.1, -0.05, 0.2), (np.cos(0.2), np.sin(0.2), 0.0, 0.0))
    pose = lambda t: (np.array([0.3 * t, 0.0, 1.0]), yaw_quaternion(rate * t))  # noqa: E731
    w = cufund.worlds.load("imav2025_tunnel")
    pc, truth = L.Lidar(L.mid360(), L.LidarParams(pose_samples=8), T_BL).scan_with_truth(w, pose, 0.0)
    R_BL, t_BL = T_BL.R, np.array(T_BL.t)
    for i in np.linspace(0, len(pc) - 1, 200).astype(int):
        p_WB, q_WB = pose(pc.t + pc.dt[i])
        R_WB = quat_to_matrix(q_WB)
        expect = R_WB @ (R_BL @ pc.points_L[i] + t_BL) + p_WB
        np.testing.assert_allclose(truth.points_W[i], expect, atol=2e-4)


def test_noise_dropout_and_determinism():
    params = L.LidarParams(range_noise_std=0.05, dropout=0.3, seed=7, range_max=100.0)
    world = wall_world()
    a, a_truth = L.Lidar(L.os1_64(), params).scan_with_truth(world, static_pose(), 0.0)
    b = L.Lidar(L.os1_64(), params).scan(world, static_pose(), 0.0)
    c = L.Lidar(L.os1_64(), L.LidarParams(range_noise_std=0.05, dropout=0.3, seed=8, range_max=100.0)).scan(
        world, static_pose(), 0.0
    )
    clean = L.Lidar(L.os1_64(), L.LidarParams(range_max=100.0)).scan(world, static_pose(), 0.0)
    np.testing.assert_array_equal(a.ranges, b.ranges)
    np.testing.assert_array_equal(a.points_L, b.points_L)
    assert len(a) != len(c) or not np.array_equal(a.ranges, c.ranges)
    assert len(a) / len(clean) == pytest.approx(0.7, abs=0.02)
    err = a.ranges - np.linalg.norm(a_truth.points_W.astype(float), axis=1)
    assert np.std(err) == pytest.approx(0.05, rel=0.05)
    assert abs(np.mean(err)) < 0.003


def test_range_limits_and_intensity_from_incidence_angle():
    w = cufund.World()
    w.add_plane((200.0, 200.0), (0.0, 0.0, 0.0), label="floor")
    h = 2.0
    pc = L.Lidar(L.vlp16(), L.LidarParams(range_min=3.0, range_max=20.0)).scan(w, static_pose((0, 0, h)), 0.0)
    assert pc.ranges.min() >= 3.0 and pc.ranges.max() <= 20.0
    assert len(pc) > 1000
    refl = w.objects[0].reflectivity
    np.testing.assert_allclose(pc.intensity, refl * h / pc.ranges, rtol=1e-4)


def test_scan_counts_frames_and_accepts_a_raycast_scene():
    w = cufund.worlds.load("corridor")
    lid = L.Lidar(L.mid360())
    a, a_truth = lid.scan_with_truth(w.raycast_scene, static_pose((5, 0, 1)), 0.0)
    b = lid.scan(w, static_pose((5, 0, 1)), 0.1)
    assert (a.frame, b.frame) == (0, 1)
    assert np.all(a.intensity <= 1.0) and np.all(a.intensity > 0)
    assert set(np.unique(a_truth.object_ids)) <= {0, 1, 2, 3}


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"range_min": -1.0}, "range_min"),
        ({"range_max": 0.05}, "range_max"),
        ({"range_noise_std": np.nan}, "range_noise_std"),
        ({"dropout": 1.0}, "dropout"),
        ({"pose_samples": 1}, "pose_samples"),
    ],
)
def test_bad_params_raise(kwargs, message):
    with pytest.raises(ValueError, match=message):
        L.LidarParams(**kwargs)


def test_bad_pose_and_target_raise():
    lid = L.Lidar(L.vlp16())
    with pytest.raises(ValueError, match="target must be a cufund.World"):
        lid.scan("world", static_pose(), 0.0)
    with pytest.raises(ValueError, match=r"p_W as 3 finite numbers"):
        lid.scan(wall_world(), lambda t: (np.array([np.nan, 0, 0]), np.array([1.0, 0, 0, 0])), 0.0)
    with pytest.raises(ValueError, match=r"q_WB must be 4 finite numbers"):
        lid.scan(wall_world(), lambda t: (np.zeros(3), np.zeros(3)), 0.0)
    with pytest.raises(ValueError, match="pattern must provide"):
        L.Lidar(object())


def test_scan_rays_validates_knots():
    d = np.array([[1.0, 0.0, 0.0]])
    q = np.array([[1.0, 0, 0, 0], [1.0, 0, 0, 0]])
    with pytest.raises(ValueError, match="knot_t must be strictly increasing"):
        cufund._core.lidar.scan_rays(d, [0.0], [0.0, 0.0], np.zeros((2, 3)), q)
    with pytest.raises(ValueError, match=r"knot_q must have shape \(2, 4\)"):
        cufund._core.lidar.scan_rays(d, [0.0], [0.0, 1.0], np.zeros((2, 3)), q[:, :3])
    with pytest.raises(ValueError, match=r"knot_t must have shape \(K,\) with K >= 2"):
        cufund._core.lidar.scan_rays(d, [0.0], [0.0], np.zeros((1, 3)), q[:1])


def test_lidar_component_publishes_distorted_frames_in_the_simulator():
    quad = cufund.Quadrotor(cufund.vehicle.presets.cu_astro())
    quad.hover([0.0, 0.0, 1.0])
    quad.state.v[:] = [1.0, 0.0, 0.0]  # coasting towards the wall at x = 10 m
    sim = cufund.Simulator(quad, physics_rate_hz=1000, record_topics=())
    T_BL = Transform((0.05, 0.0, 0.1))
    comp = sim.add(
        cufund.sensors.LidarComponent(
            L.Lidar(L.mid360(), L.LidarParams(range_max=100.0), T_BL), wall_world(), rate_hz=200.0
        )
    )
    frames = []

    class Grab(cufund.Component):
        name, rate_hz = "grab", 30.0  # slower than the LiDAR: the subscription still delivers every frame
        inputs = (cufund.Topics.POINT_CLOUD,)

        def setup(self, bus):
            self.sub = bus.subscribe(cufund.Topics.POINT_CLOUD)

        def step(self, t, bus):
            frames.extend(self.sub.take())

    sim.add(Grab())
    result = sim.run(0.5)
    assert [f.frame for f in frames] == [0, 1, 2, 3]
    assert [f.t for f in frames] == pytest.approx([0.0, 0.1, 0.2, 0.3])
    x_of_t = lambda t: np.interp(t, result.states["t"], result.states["p_W"][:, 0])  # noqa: E731
    for f in frames:
        assert f.dt.min() >= 0.0 and f.dt.max() < 0.1
        np.testing.assert_allclose(f.points_L[:, 0], 10.0 - x_of_t(f.t + f.dt) - 0.05, atol=2e-3)
    assert comp.topic == cufund.Topics.POINT_CLOUD
    with pytest.raises(ValueError, match="multiple of the LiDAR frame rate"):
        cufund.sensors.LidarComponent(L.Lidar(L.mid360()), wall_world(), rate_hz=15.0)


def test_unsigned_triangle_indices_beyond_32_bits_are_rejected_not_wrapped():
    scene = cufund.sensors.RaycastScene()
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    with pytest.raises(ValueError, match="triangles must hold vertex indices in"):
        scene.add_triangles(v, np.array([[0, 1, 2 + 2**32]], np.uint64))


def test_adding_triangles_while_casting_on_another_thread_is_safe():
    """Embree forbids changing a scene during traversal: the scene serialises the two."""
    import threading

    scene = cufund.sensors.RaycastScene()
    v = np.array([[-5, -5, 0], [5, -5, 0], [0, 5, 0]], np.float32)
    scene.add_triangles(v, np.array([[0, 1, 2]], np.uint32))
    rays = np.tile(np.array([0, 0, 1, 0, 0, -1], np.float32), (200_000, 1))
    errors = []

    def cast():
        try:
            for _ in range(20):
                assert np.all(scene.cast_rays(rays)["t_hit"] <= 1.0 + 1e-5)
        except Exception as e:
            errors.append(e)

    t = threading.Thread(target=cast)
    t.start()
    for k in range(200):
        scene.add_triangles(v + np.float32(10 + k), np.array([[0, 1, 2]], np.uint32))
    t.join()
    assert not errors and scene.num_triangles == 201


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"t": np.array([np.nan])}, "t must be finite"),
        ({"knot_q": np.array([[0.0, 0, 0, 0], [1.0, 0, 0, 0]])}, "knot_q must hold unit quaternions"),
        ({"d_L": np.zeros((1, 3))}, "d_L must hold non-zero directions"),
    ],
)
def test_scan_rays_rejects_non_finite_and_degenerate_input(change, message):
    from cufund import _core

    args = {
        "d_L": np.array([[1.0, 0, 0]]),
        "t": np.array([0.05]),
        "knot_t": np.array([0.0, 0.1]),
        "knot_p": np.zeros((2, 3)),
        "knot_q": np.array([[1.0, 0, 0, 0], [1.0, 0, 0, 0]]),
    }
    args.update(change)
    with pytest.raises(ValueError, match=message):
        _core.lidar.scan_rays(**args)


# --- the one-call frame (scan_frame) and the C++ Mid-360 pattern, against NumPy references -------------------------


def _numpy_frame(scene, d_L, t, channel, t0, knots, p_k, q_k, rmin, rmax, noise, keep, dropout, refl):
    """The LiDAR model as it was written in NumPy: scan_rays, cast_rays, then the range model."""
    rays = cufund._core.lidar.scan_rays(d_L, t0 + t, knots, p_k, q_k)
    hit = scene.cast_rays(rays, coherent=False)
    r_true = hit["t_hit"].astype(np.float64)
    valid = (r_true >= rmin) & (r_true <= rmax)
    if keep is not None:
        valid &= keep >= dropout
    idx = np.nonzero(valid)[0]
    r_meas = r_true[idx] if noise is None else np.maximum(r_true[idx] + noise[idx], 0.0)
    ids = hit["geometry_ids"][idx]
    cos_inc = np.abs(np.sum(hit["normals"][idx] * rays[idx, 3:], axis=1))
    return {
        "dt": t[idx],
        "points_L": (d_L[idx] * r_meas[:, None]).astype(np.float32),
        "ranges": r_meas,
        "intensity": np.clip((refl[ids] if refl is not None else 1.0) * cos_inc, 0.0, 1.0),
        "channel": channel[idx],
        "points_W": (rays[idx, :3] + rays[idx, 3:] * r_true[idx, None]).astype(np.float32),
        "object_ids": ids,
    }


@pytest.mark.parametrize("with_model", [False, True])
def test_scan_frame_equals_rays_cast_one_by_one_and_the_numpy_range_model(with_model):
    """The one-call frame against scan_rays, single-ray casting and the range model as NumPy wrote it."""
    from cufund.worlds.builtin import imav2025_tunnel

    world = imav2025_tunnel()
    scene = world.raycast_scene
    rays_L = L.mid360().frame(4)
    d_L, n = rays_L.directions(), len(rays_L.t)
    t0 = 2.0
    knots = t0 + np.linspace(0.0, 0.1, 32)
    p_k = np.column_stack([np.linspace(-2.5, -2.3, 32), np.linspace(0.0, 0.05, 32), np.full(32, 1.2)])
    yaw = np.linspace(0.0, 0.3, 32)
    q_k = np.column_stack([np.cos(yaw / 2), np.zeros(32), np.zeros(32), np.sin(yaw / 2)])
    rng = np.random.default_rng(3)
    noise = rng.standard_normal(n) * 0.02 if with_model else None
    keep = rng.random(n) if with_model else None
    refl = world.reflectivities() if with_model else None
    args = (scene, d_L, rays_L.t, rays_L.channel, t0, knots, p_k, q_k, 0.5, 6.0, noise, keep, 0.3, refl)
    got = cufund._core.lidar.scan_frame(*args, nthreads=2)
    want = _numpy_frame(*args)
    assert 0 < len(got["dt"]) < n  # the range window (and the dropout) removed some rays, kept others
    for key, value in want.items():  # coherent packets: distances equal to single rays' up to the last bits
        assert got[key].dtype == value.dtype, key
        if key in ("points_L", "ranges", "intensity", "points_W"):
            np.testing.assert_allclose(got[key], value, rtol=1e-6, atol=1e-6, err_msg=key)
        else:
            np.testing.assert_array_equal(got[key], value, err_msg=key)
    if not with_model:
        assert got["intensity"].dtype == np.float32


def test_scan_frame_checks_its_arguments():
    from cufund.worlds.builtin import imav2025_tunnel

    world = imav2025_tunnel()
    rays_L = L.mid360().frame(0)
    d_L, n = rays_L.directions(), len(rays_L.t)
    knots, p_k, q_k = np.array([0.0, 0.1]), np.tile([-2.5, 0.0, 1.0], (2, 1)), np.tile([1.0, 0, 0, 0], (2, 1))
    base = dict(
        scene=world.raycast_scene,
        d_L=d_L,
        t=rays_L.t,
        channel=rays_L.channel,
        t0=0.0,
        knot_t=knots,
        knot_p=p_k,
        knot_q=q_k,
        range_min=0.1,
        range_max=40.0,
    )
    for change, message in [
        ({"noise": np.zeros(n - 1)}, "noise"),
        ({"channel": rays_L.t}, "channel"),
        ({"keep_draw": np.full(n, np.nan)}, "keep_draw"),
        ({"t0": np.inf}, "t0"),
        ({"reflectivity": np.ones(1)}, "reflectivity"),
        ({"knot_q": 2 * q_k}, "knot_q"),
    ]:
        with pytest.raises(ValueError, match=message):
            cufund._core.lidar.scan_frame(**{**base, **change})


def test_mid360_pattern_is_the_documented_formula():
    p = L.mid360()
    for k in (0, 1, 299):
        r = p.frame(k)
        n = len(r.t)
        i = np.arange(n)
        t_abs = (k * n + i) / p.point_rate
        ch = i % p.lasers
        az = np.mod(2 * np.pi * (p.spin_rate * t_abs + ch / p.lasers), 2 * np.pi)
        el = (p.elevation_max + p.elevation_min) / 2 + (p.elevation_max - p.elevation_min) / 2 * np.sin(
            2 * np.pi * p.spin_rate * p.sweep_ratio * t_abs + np.pi * ch / p.lasers
        )
        np.testing.assert_allclose(r.t, i / p.point_rate, rtol=0, atol=1e-15)
        np.testing.assert_allclose(r.azimuth, az, rtol=0, atol=1e-12)
        np.testing.assert_allclose(r.elevation, el, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(r.channel, ch)
        assert r.channel.dtype == np.int32
        d = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], 1)
        np.testing.assert_allclose(r.directions(), d, rtol=0, atol=1e-12)


def test_lidar_component_samples_its_poses_as_the_scalar_pose_function_does():
    from cufund.geometry import sample_poses
    from cufund.sensors.lidar_component import LidarComponent
    from cufund.worlds.builtin import imav2025_tunnel

    comp = LidarComponent(L.Lidar(L.mid360(), T_BL=Transform((0.0, 0.0, 0.08), yaw_quaternion(0.2))), imav2025_tunnel())
    rng = np.random.default_rng(5)
    for k in range(12):  # 100 Hz samples of a tumbling body, one sign flipped on purpose
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        comp._t.append(0.01 * k)
        comp._p.append(rng.normal(size=3))
        comp._q.append(-q if k == 5 else q)
    times = np.linspace(0.0, 0.1, 32)
    many = comp._pose_fn.many(times)
    from cufund.sensors.lidar import _compose

    want = sample_poses(comp._pose, times, comp.lidar.T_BL)
    got = _compose(*many, comp.lidar.T_BL)
    np.testing.assert_array_equal(got[0], want[0])
    np.testing.assert_array_equal(got[1], want[1])
