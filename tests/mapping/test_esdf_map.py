"""cufund.mapping.EsdfMap: occupancy from point clouds, incremental == full recompute, queries, errors."""

import math

import numpy as np
import pytest
from scipy import ndimage

from cufund import ConfigError
from cufund import mapping as esdf


def make_map(**kw):
    args = {"resolution": 0.1, "size": (3.0, 2.4, 1.6), "origin_W": (-1.0, -1.2, -0.2)} | kw
    return esdf.EsdfMap(esdf.EsdfMapParams(**args))


def ray_box_hits(origin, directions, lo, hi):
    """Exact first intersection of rays origin + t d (t > 0) with the box [lo, hi]; NaN rows on a miss."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - origin) / directions
        t2 = (hi - origin) / directions
    t_near = np.nanmax(np.minimum(t1, t2), axis=1)
    t_far = np.nanmin(np.maximum(t1, t2), axis=1)
    hit = (t_near <= t_far) & (t_near > 0)
    p = np.full(directions.shape, np.nan)
    p[hit] = origin + t_near[hit, None] * directions[hit]
    return p


MID360_ELEVATIONS_DEG = np.linspace(-7.0, 52.0, 40)


def mid360_directions(n_az=360, elevations_deg=MID360_ELEVATIONS_DEG):
    az = np.linspace(0, 2 * np.pi, n_az, endpoint=False)
    a, e = np.meshgrid(az, np.radians(elevations_deg), indexing="ij")
    return np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=-1).reshape(-1, 3)


def test_scanning_a_box_recovers_the_box():
    res = 0.05
    m = make_map(resolution=res, size=(4.0, 4.0, 2.0), origin_W=(-2.0, -2.0, -0.5))
    lo, hi = np.array([0.6, -0.4, -0.3]), np.array([1.2, 0.5, 0.9])
    dirs = mid360_directions()
    hit_voxels = set()
    for origin in ([0.0, 0.0, 0.3], [-0.2, 0.4, 0.5], [0.1, -0.5, 0.2]):
        origin = np.asarray(origin)
        pts = ray_box_hits(origin, dirs, lo, hi)
        stats = m.insert_scan(pts, origin)
        n_hit = int(np.sum(np.all(np.isfinite(pts), axis=1)))
        assert stats.points == len(dirs) and stats.nan_points == len(dirs) - n_hit > 0
        ok = np.all(np.isfinite(pts), axis=1)
        hit_voxels |= {tuple(v) for v in np.floor((pts[ok] - m.params.origin_W) / res).astype(int)}
    occ = m.occupied()
    occupied = {tuple(v) for v in np.argwhere(occ)}
    # Every occupied voxel overlaps the box, and (almost) every voxel a beam ended in stayed occupied.
    centres = m.occupied_points()
    assert np.all(centres >= lo - res / 2 - 1e-9) and np.all(centres <= hi + res / 2 + 1e-9)
    assert len(occupied & hit_voxels) >= 0.97 * len(hit_voxels)
    assert occupied <= hit_voxels
    # The face seen by the sensors is closed: the x = 0.6 voxel layer is occupied over the part of the
    # face inside the field of view (elevation >= -7 deg: z >= 0.15 m here) and away from its edges.
    i_face = int(math.floor((0.6 - m.params.origin_W[0]) / res))
    j = np.arange(int((-0.4 + 2.0) / res) + 1, int((0.5 + 2.0) / res) - 1)
    k = np.arange(int((0.2 + 0.5) / res), int((0.9 + 0.5) / res) - 1)
    assert np.all(occ[i_face][np.ix_(j, k)])
    # Free space was observed between sensor and box.
    assert np.all(m.log_odds()[int(2.0 / res) + 2 : i_face - 1, int(2.0 / res), int(0.8 / res)] < 0)
    # And the field: a point 0.3 m in front of the face is 0.3 m away (within a voxel).
    d = m.distance(np.array([0.3, 0.05, 0.3]))
    assert abs(d - 0.3) <= res
    # Occupied face voxels are one voxel deep inside (signed); the unobserved interior counts as free.
    c = np.array([m.voxel_centers("x")[i_face], m.voxel_centers("y")[j[5]], m.voxel_centers("z")[k[5]]])
    assert m.distance(c) == pytest.approx(-res, abs=1e-12)


def test_incremental_equals_full_recompute_after_random_inserts_and_removes():
    m = make_map()
    rng = np.random.default_rng(0)
    n = np.array(m.shape)
    for step in range(40):
        count = 500 if step % 8 == 0 else int(rng.integers(1, 30))
        ijk = rng.integers(0, n, size=(count, 3))
        if step % 3 == 0:  # clustered edits: a blob appears or disappears
            ijk = np.clip(rng.integers(0, n) + rng.integers(-3, 4, size=(count, 3)), 0, n - 1)
        m.set_occupied(ijk, rng.random(count) < (0.7 if step < 20 else 0.3))
        outside, inside = (a.copy() for a in m.squared_distances())
        full = m.copy()
        full.recompute()
        np.testing.assert_array_equal(full.squared_distances()[0], outside)
        np.testing.assert_array_equal(full.squared_distances()[1], inside)
    occ = m.occupied()
    ref = ndimage.distance_transform_edt(~occ, sampling=0.1) - ndimage.distance_transform_edt(occ, sampling=0.1)
    np.testing.assert_allclose(m.distances(), ref, rtol=1e-14, atol=0)
    np.testing.assert_allclose(m.distances(), esdf.edt(occ, voxel_size=0.1, signed=True), rtol=1e-14, atol=0)


def test_incremental_equals_full_recompute_after_random_scans():
    m = make_map(max_range=2.0)
    rng = np.random.default_rng(1)
    for step in range(15):
        origin = np.array([0.2 * math.sin(step), 0.1 * step - 0.7, 0.6])
        pts = origin + rng.normal(size=(800, 3)) * [1.5, 1.2, 0.5]
        pts[:5] = np.nan
        stats = m.insert_scan(pts, origin)
        assert stats.nan_points == 5 and stats.outside + stats.beyond_range > 0
        full = m.copy()
        full.recompute()
        for a, b in zip(m.squared_distances(), full.squared_distances(), strict=True):
            np.testing.assert_array_equal(a, b)
    assert m.occupied().any() and (~m.occupied()).any()
    occ = m.occupied()
    np.testing.assert_allclose(m.distances(), esdf.edt(occ, voxel_size=0.1, signed=True), rtol=1e-14, atol=0)


def test_gradient_matches_finite_differences():
    m = make_map(size=(2.0, 2.0, 1.0))
    rng = np.random.default_rng(2)
    m.set_occupied(rng.integers(0, m.shape, size=(15, 3)))
    p = rng.uniform([-0.9, -1.1, -0.1], [0.9, 0.7, 0.7], size=(400, 3))
    d, g = m.distance_and_gradient(p)
    np.testing.assert_array_equal(d, m.distance(p))
    eps = 1e-6
    for a in range(3):
        e = np.zeros(3)
        e[a] = eps
        fd = (m.distance(p + e) - m.distance(p - e)) / (2 * eps)
        # The trilinear interpolant is smooth inside a cell; skip points within eps of a cell face.
        u = (p[:, a] - m.params.origin_W[a]) / 0.1 - 0.5
        inside = np.abs(u - np.round(u)) > 1e-4
        np.testing.assert_allclose(g[inside, a], fd[inside], atol=1e-6)
    # Single points give scalars; distances at voxel centres are the voxel values.
    centre = np.array(m.params.origin_W) + 0.1 * (np.array([7, 3, 4]) + 0.5)
    assert m.distance(centre) == pytest.approx(m.distances()[7, 3, 4], abs=1e-12)


def test_slices_and_occupied_points():
    m = make_map()
    m.set_occupied(np.array([[5, 6, 7], [10, 2, 7], [3, 3, 3]]))
    s = m.slice("z", -0.2 + 0.75)  # layer k = 7
    np.testing.assert_array_equal(s, m.distances()[:, :, 7])
    assert s[5, 6] < 0 and s[10, 2] < 0
    np.testing.assert_allclose(m.voxel_centers("y")[:2], [-1.15, -1.05])
    pts = m.occupied_points()
    np.testing.assert_allclose(
        sorted(pts.tolist()),
        sorted((np.array([[5, 6, 7], [10, 2, 7], [3, 3, 3]]) * 0.1 + [-0.95, -1.15, -0.15]).tolist()),
    )
    with pytest.raises(ValueError, match='axis must be "x", "y" or "z"'):
        m.slice("w", 0.0)


def test_unsigned_map_is_zero_inside():
    m = make_map(signed=False)
    m.set_occupied(np.array([[4, 4, 4]]))
    assert m.distances()[4, 4, 4] == 0.0
    assert m.distances()[4, 4, 6] == pytest.approx(0.2)


def test_points_outside_the_map_and_nan_are_counted_not_fatal():
    m = make_map()
    pts = np.array([[10.0, 0.0, 0.5], [np.nan, 0.0, 0.0], [0.5, 0.0, 0.5], [0.0, np.inf, 0.0]])
    s = m.insert_scan(pts, [0.0, 0.0, 0.5])
    assert (s.points, s.nan_points, s.outside, s.hit_voxels) == (4, 2, 1, 1)
    with pytest.raises(ValueError, match=r"p_W must be finite \[m\], got \[nan, 0.0, 0.0\] in row 0"):
        m.distance(np.array([[np.nan, 0, 0]]))
    with pytest.raises(ValueError, match=r"p_W must be finite \[m\], got \[inf, 0.0, 0.5\] in row 1"):
        m.distance_and_gradient(np.array([[0.5, 0, 0.5], [np.inf, 0, 0.5]]))


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda m: m.insert_scan(np.zeros((10, 2)), [0, 0, 0]), r"points_W must have shape \(N, 3\), got \(10, 2\)"),
        (lambda m: m.insert_scan(np.zeros((10, 3)), [0, np.nan, 0]), "origin_W must be finite"),
        (lambda m: m.insert_scan(np.zeros((10, 3)), [0, 0]), r"origin_W must have shape \(3,\)"),
        (lambda m: m.insert_scan(np.array([["a", "b", "c"]]), [0, 0, 0]), "points_W must have a real numeric dtype"),
        (lambda m: m.distance(np.zeros((4, 4))), r"points_W must have shape \(N, 3\), got \(4, 4\)"),
        (lambda m: m.set_occupied(np.array([[0, 0, 99]])), r"outside the map shape \(30, 24, 16\)"),
        (lambda m: m.set_occupied(np.zeros((2, 3))), r"ijk must be an integer array of shape \(M, 3\)"),
    ],
)
def test_bad_input_raises_clear_errors(call, message):
    with pytest.raises(ValueError, match=message):
        call(make_map())


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"resolution": 0.0}, "resolution must be finite and > 0"),
        ({"resolution": -0.1}, "resolution must be finite and > 0"),
        ({"size": (1.0, 0.0, 1.0)}, "size must be > 0"),
        ({"size": (1.0, 1.0)}, "size must be 3 finite real numbers"),
        ({"log_odds_hit": -1.0}, "log_odds_hit must be finite and > 0"),
        ({"log_odds_occupied": 5.0}, "log_odds_min <= log_odds_occupied < log_odds_max"),
        ({"max_range": 0.0}, "max_range must be > 0"),
        ({"nthreads": -2}, "nthreads must be an integer >= 0"),
    ],
)
def test_bad_params_raise_config_errors(kwargs, message):
    args = {"resolution": 0.1, "size": (1.0, 1.0, 1.0)} | kwargs
    with pytest.raises(ConfigError, match=message):
        esdf.EsdfMapParams(**args)


def test_params_from_dict_reject_unknown_keys_and_round_shape_up():
    p = esdf.EsdfMapParams.from_dict({"resolution": 0.15, "size": [1.0, 0.3, 0.31]})
    assert p.shape == (7, 2, 3)
    with pytest.raises(ConfigError, match="unknown key 'resolutoin'"):
        esdf.EsdfMapParams.from_dict({"resolutoin": 0.1, "size": [1, 1, 1]})


def test_map_satisfies_the_distance_field_interface():
    assert isinstance(make_map(), esdf.DistanceField)


def test_sensor_outside_the_map_marks_the_part_of_the_beam_inside():
    m = make_map()  # x in [-1, 2]
    s = m.insert_scan(np.array([[0.55, 0.05, 0.55]]), [-3.0, 0.05, 0.55])
    assert (s.hit_voxels, s.outside, s.free_voxels) == (1, 0, 15)  # voxels x = 0..14 free, 15 hit
    lo = m.log_odds()[:, 12, 7]
    assert np.all(lo[:15] < 0) and lo[15] > 0 and np.all(lo[16:] == 0)


def test_scanning_a_box_world_with_the_simulated_lidar_recovers_the_box():
    from cufund import World
    from cufund.sensors import Lidar, mid360, mid360_params

    res = 0.05
    lo, hi = np.array([0.6, -0.4, 0.0]), np.array([1.2, 0.5, 1.2])
    world = World("box")
    world.add_box(hi - lo, (lo + hi) / 2)
    lidar = Lidar(mid360(), mid360_params(range_noise_std=0.0))
    m = make_map(resolution=res, size=(4.0, 4.0, 2.0), origin_W=(-2.0, -2.0, -0.5))
    hit_voxels = set()
    for k, p in enumerate(([0.0, 0.0, 0.3], [-0.2, 0.4, 0.5], [0.1, -0.5, 0.2])):
        p_W = np.asarray(p, dtype=float)
        _, truth = lidar.scan_with_truth(world, lambda t, p_W=p_W: (p_W, np.array([1.0, 0.0, 0.0, 0.0])), t0=0.1 * k)
        points_W = truth.points_W.astype(float)  # noise-free hits (range_noise_std=0), world frame
        assert len(points_W) > 1000
        m.insert_scan(points_W, p_W)
        hit_voxels |= {tuple(v) for v in np.floor((points_W - m.params.origin_W) / res).astype(int)}
    occupied = {tuple(v) for v in np.argwhere(m.occupied())}
    centres = m.occupied_points()
    assert np.all(centres >= lo - res / 2 - 1e-6) and np.all(centres <= hi + res / 2 + 1e-6)
    assert occupied <= hit_voxels and len(occupied) >= 0.97 * len(hit_voxels)
    # A point 0.3 m in front of the face seen by the sensors is 0.3 m from the box (within a voxel).
    assert abs(m.distance(np.array([0.3, 0.05, 0.4])) - 0.3) <= res


def test_esdf_mapper_integrates_the_lidar_topic_in_the_simulator():
    import cufund
    from cufund.geometry import Transform
    from cufund.sensors import Lidar, LidarComponent, mid360

    lo, hi = np.array([0.6, -0.4, 0.0]), np.array([1.2, 0.5, 1.2])
    world = cufund.World("box")
    world.add_box(hi - lo, (lo + hi) / 2)
    quad = cufund.Quadrotor(cufund.vehicle.presets.cu_astro())
    quad.hover([0.0, 0.0, 0.6])
    quad.state.v[:] = [0.3, 0.0, 0.0]  # drifting towards the box: the frames are motion-distorted
    sim = cufund.Simulator(quad, physics_rate_hz=1000, record_topics=())
    T_BL = Transform((0.05, 0.0, 0.1))
    sim.add(LidarComponent(Lidar(mid360(), T_BL=T_BL), world, rate_hz=200.0))
    res = 0.05
    mapper = sim.add(
        esdf.EsdfMapper(
            esdf.EsdfMapParams(resolution=res, size=(4.0, 4.0, 2.0), origin_W=(-2.0, -2.0, -0.5)),
            T_BL=T_BL,
            rate_hz=200.0,
        )
    )
    sim.run(0.45)
    assert mapper.frames == 4
    m = mapper.map
    centres = m.occupied_points()
    assert len(centres) > 100
    assert np.all(centres >= lo - res / 2 - 1e-6) and np.all(centres <= hi + res / 2 + 1e-6)
    assert abs(m.distance(np.array([0.3, 0.05, 0.6])) - 0.3) <= res


def test_a_map_too_long_for_exact_integer_distances_is_rejected():
    # 50 000 voxels along x: squared distances would overflow the exact int32 storage.
    with pytest.raises(ValueError, match="diagonal of at most 46340 voxels"):
        esdf.EsdfMap(esdf.EsdfMapParams(resolution=0.1, size=(5000.0, 0.1, 0.1), origin_W=(0.0, 0.0, 0.0)))


def test_scans_give_the_same_map_on_one_thread_and_on_all():
    """Beams are traversed in parallel; the occupancy and the field must not depend on it."""
    maps = [make_map(max_range=2.0, nthreads=t) for t in (1, 0)]
    rng = np.random.default_rng(5)
    for step in range(6):
        origin = np.array([0.1 * step - 0.3, 0.2, 0.6])
        pts = origin + rng.normal(size=(3000, 3)) * [1.5, 1.2, 0.5]
        stats = [m.insert_scan(pts, origin) for m in maps]
        assert stats[0] == stats[1]
    np.testing.assert_array_equal(maps[0].log_odds(), maps[1].log_odds())
    np.testing.assert_array_equal(maps[0].distances(), maps[1].distances())


def test_esdf_map_pickles_with_its_occupancy_and_distances(rng):
    import pickle

    m = make_map()
    origin = np.array([0.2, 0.3, 0.5])
    for _ in range(3):
        m.insert_scan(origin + rng.uniform(-1.0, 1.5, (400, 3)), origin)
    m.set_occupied(np.array([[3, 4, 5], [10, 10, 2]]))
    c = pickle.loads(pickle.dumps(m))
    assert c.params == m.params
    assert np.array_equal(c.log_odds(), m.log_odds())
    assert np.array_equal(c.occupied(), m.occupied())
    assert c.distances().tobytes() == m.distances().tobytes()
    for a, b in zip(c.squared_distances(), m.squared_distances(), strict=True):
        assert np.array_equal(a, b)
    # Both continue identically: the same scan on each gives the same statistics and fields.
    scan = origin + rng.uniform(-1.0, 1.5, (300, 3))
    assert c.insert_scan(scan, origin) == m.insert_scan(scan, origin)
    assert c.distances().tobytes() == m.distances().tobytes()
    q = rng.uniform(0, 2, (50, 3))
    assert c.distance(q).tobytes() == m.distance(q).tobytes()


def test_esdf_map_voxel_count_is_limited_and_configurable():
    import cufund.core.limits

    with pytest.raises(ConfigError, match=r"at most grid_max_voxels = 134217728 voxels"):
        make_map(resolution=0.01, size=(100.0, 100.0, 10.0))  # 1e9 voxels, ~20 GB
    with cufund.core.limits.override(grid_max_voxels=1000):
        with pytest.raises(ConfigError, match=r"got \(20, 20, 20\) = 8000"):
            make_map(resolution=0.1, size=(2.0, 2.0, 2.0))
