"""Batched ESDF updates: several scans per call, merged beams, LiDAR frames placed in C++ (issue 14's speed).

References: the per-scan, per-point ``insert_scan`` (the map the batch must equal, or bound), numpy's pose
interpolation (``cufund.geometry.interpolate_poses``) and scipy's EDT of the resulting occupancy.
"""

import numpy as np
import pytest
from scipy import ndimage

from cufund import mapping as esdf
from cufund.geometry import Transform, interpolate_poses, quat_mul, quat_to_matrix


def make_map(**kw):
    args = {"resolution": 0.1, "size": (3.0, 2.4, 1.6), "origin_W": (-1.0, -1.2, -0.2)} | kw
    return esdf.EsdfMap(esdf.EsdfMapParams(**args))


def scipy_signed(m):
    """scipy's exact signed EDT of the map's occupancy [m]: the field the map must hold."""
    occ = m.occupied()
    h = m.params.resolution
    return ndimage.distance_transform_edt(~occ) * h - ndimage.distance_transform_edt(occ) * h


def random_scans(rng, n_scans=6, n_points=3000):
    scans = []
    for step in range(n_scans):
        origin = np.array([0.1 * step - 0.3, 0.2, 0.6])
        pts = origin + rng.normal(size=(n_points, 3)) * [1.5, 1.2, 0.5]
        pts[rng.random(n_points) < 0.01] = np.nan
        scans.append((pts, origin))
    return scans


def room_scan(origin, n_az=720, n_el=48):
    """A Mid-360-like scan of a room (floor z = 0, walls at x = +-1.3, y = +-1.1, a pillar): exact hits."""
    az = np.linspace(0, 2 * np.pi, n_az, endpoint=False) + 0.37 * origin[0]
    el = np.radians(np.linspace(-7.0, 52.0, n_el))
    a, e = np.meshgrid(az, el, indexing="ij")
    d = np.stack([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)], axis=-1).reshape(-1, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.full(len(d), np.inf)
        for axis, planes in ((0, (-1.3, 1.3)), (1, (-1.1, 1.1)), (2, (0.0,))):
            for c in planes:
                tc = (c - origin[axis]) / d[:, axis]
                t = np.where((tc > 0) & (tc < t), tc, t)
        # The pillar: a box 0.2 x 0.2 m around (0.5, -0.4), full height.
        lo, hi = np.array([0.4, -0.5, -1.0]), np.array([0.6, -0.3, 5.0])
        t1, t2 = (lo - origin) / d, (hi - origin) / d
        near, far = np.nanmax(np.minimum(t1, t2), axis=1), np.nanmin(np.maximum(t1, t2), axis=1)
    t = np.where((near <= far) & (near > 0) & (near < t), near, t)
    return origin + t[:, None] * d


def test_insert_scans_equals_one_insert_scan_per_scan(rng):
    scans = random_scans(rng)
    one, batch = make_map(max_range=2.0), make_map(max_range=2.0)
    singles = [one.insert_scan(p, o) for p, o in scans]
    s = batch.insert_scans(scans)
    np.testing.assert_array_equal(batch.log_odds(), one.log_odds())
    for a, b in zip(batch.squared_distances(), one.squared_distances(), strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_allclose(batch.distances(), scipy_signed(batch), rtol=1e-12)
    for name in ("points", "nan_points", "outside", "beyond_range", "beams", "hit_voxels", "free_voxels"):
        assert getattr(s, name) == sum(getattr(x, name) for x in singles), name
    assert s.nan_points > 0 and s.beyond_range > 0 and s.outside > 0
    # A voxel freed then hit again within the batch is not a net change: flips are net, per batch.
    assert s.flipped_voxels == int(batch.occupied().sum())


def test_insert_scans_on_one_thread_and_on_all_give_the_same_map(rng):
    scans = random_scans(rng, n_scans=9)
    maps = [make_map(max_range=2.0, nthreads=t, merge_beams=merge) for merge in (False, True) for t in (1, 0)]
    stats = [m.insert_scans(scans) for m in maps]
    for k in (0, 2):
        assert stats[k] == stats[k + 1]
        np.testing.assert_array_equal(maps[k].log_odds(), maps[k + 1].log_odds())
        np.testing.assert_array_equal(maps[k].distances(), maps[k + 1].distances())


def test_merged_beams_keep_the_hits_and_free_a_subset_of_the_per_point_free_space():
    """One beam per end voxel: each scan's hits are the per-point ones and its free voxels a subset, so every
    log-odds stays >= the per-point map's (the update is monotone), the occupied voxels a superset; stated
    bound on a LiDAR-like room: the merged scan frees >= 95 % of the voxels, and after 8 scans at most 1 % of
    the occupied voxels are extra."""
    kw = {"resolution": 0.1, "size": (3.0, 2.6, 2.0), "origin_W": (-1.5, -1.3, -0.3), "max_range": 2.5}
    ref, merged = make_map(**kw), make_map(merge_beams=True, **kw)
    origins = [np.array([-0.6 + 0.15 * k, 0.1 * np.sin(k), 0.5 + 0.05 * k]) for k in range(8)]
    for k, origin in enumerate(origins):
        pts = room_scan(origin)
        if k == 0:  # one scan into empty maps: compare its sets directly
            fresh_ref, fresh_merged = make_map(**kw), make_map(merge_beams=True, **kw)
            sr, sm = fresh_ref.insert_scan(pts, origin), fresh_merged.insert_scan(pts, origin)
            lr, lm = fresh_ref.log_odds(), fresh_merged.log_odds()
            np.testing.assert_array_equal(lm > 0, lr > 0)  # the same hit voxels
            assert np.all((lm < 0) <= (lr < 0))  # free: a subset
            assert sm.hit_voxels == sr.hit_voxels and sm.beams < 0.5 * sr.beams
            assert sm.free_voxels >= 0.95 * sr.free_voxels
        ref.insert_scan(pts, origin)
        merged.insert_scan(pts, origin)
        assert np.all(merged.log_odds() >= ref.log_odds())
    occ_ref, occ_merged = ref.occupied(), merged.occupied()
    assert np.all(occ_ref <= occ_merged)
    assert occ_merged.sum() - occ_ref.sum() <= 0.01 * occ_ref.sum()
    np.testing.assert_allclose(merged.distances(), scipy_signed(merged), rtol=1e-12)


def random_knots(rng, t0, t1, n):
    t = np.sort(rng.uniform(t0, t1, n))
    p = np.cumsum(rng.normal(scale=0.02, size=(n, 3)), axis=0) + [0.2, 0.1, 0.6]
    q = np.array([1.0, 0.0, 0.0, 0.0]) + rng.normal(scale=0.05, size=(n, 4))
    q[n // 2] *= -1.0  # a sign flip between knots: interpolation must take the short way
    return t, p, q


def test_insert_frames_places_points_as_interpolate_poses_does(rng):
    """LiDAR frames placed in C++ with per-point pose interpolation == numpy placement + insert_scans."""
    T_BL = Transform(
        (0.05, -0.02, 0.08), tuple(quat_mul(np.array([0.99, 0.0, 0.1, 0.0]), np.array([1.0, 0.0, 0.0, 0.1])))
    )
    knots = random_knots(rng, -0.05, 0.35, 40)
    frames, scans = [], []
    for k in range(3):
        n = 2000
        t = 0.1 * k + np.sort(rng.uniform(0.0, 0.1, n))
        points_L = (rng.normal(size=(n, 3)) * [1.5, 1.2, 0.5]).astype(np.float32)
        t_mid = 0.1 * k + 0.05
        frames.append((points_L, t, t_mid))
        p_WB, R_WB = interpolate_poses(*knots, t)
        p_WL = p_WB + R_WB @ np.asarray(T_BL.t)
        points_W = p_WL + np.einsum("nij,nj->ni", R_WB @ T_BL.R, points_L.astype(float))
        mp, mR = interpolate_poses(*knots, np.array([t_mid]))
        scans.append((points_W, mp[0] + mR[0] @ np.asarray(T_BL.t)))
    for merge in (False, True):
        a, b = make_map(max_range=2.0, merge_beams=merge), make_map(max_range=2.0, merge_beams=merge)
        sa = a.insert_frames(frames, knots, T_BL)
        sb = b.insert_scans(scans)
        assert sa.points == 6000 and sa.hit_voxels == sb.hit_voxels and sa.beams == sb.beams
        np.testing.assert_array_equal(a.log_odds(), b.log_odds())
        np.testing.assert_array_equal(a.distances(), b.distances())
    # One knot: the pose is constant (and the quaternion normalised).
    c = make_map(max_range=2.0)
    q = np.array([[2.0, 0.0, 0.0, 0.0]])
    c.insert_frames([frames[0]], (np.array([0.0]), np.array([[0.2, 0.1, 0.6]]), q), Transform())
    d = make_map(max_range=2.0)
    d.insert_scan(frames[0][0].astype(float) @ quat_to_matrix(q[0] / 2.0).T + [0.2, 0.1, 0.6], [0.2, 0.1, 0.6])
    np.testing.assert_array_equal(c.log_odds(), d.log_odds())


@pytest.mark.parametrize(
    ("call", "error", "message"),
    [
        (
            lambda m: m.insert_scans([(np.zeros((4, 3)),)]),
            ValueError,
            r"scans\[0\] must be a tuple \(points_W, origin_W\)",
        ),
        (lambda m: m.insert_scans([(np.zeros((4, 2)), [0, 0, 0])]), ValueError, r"points_W must have shape \(N, 3\)"),
        (lambda m: m.insert_scans([(np.zeros((4, 3)), [0, np.inf, 0])]), ValueError, "origin_W must be finite"),
        (
            lambda m: m.insert_frames(
                [(np.zeros((4, 3)), np.zeros(4), 0.0)],
                (np.array([1.0, 0.5]), np.zeros((2, 3)), np.tile([1.0, 0, 0, 0], (2, 1))),
                Transform(),
            ),
            ValueError,
            "strictly ascending",
        ),
        (
            lambda m: m.insert_frames(
                [(np.zeros((4, 3)), np.zeros(4), 0.0)],
                (np.array([0.0]), np.zeros((1, 3)), np.zeros((1, 4))),
                Transform(),
            ),
            ValueError,
            "non-zero quaternion",
        ),
        (
            lambda m: m.insert_frames(
                [(np.zeros((4, 3)), np.zeros(3), 0.0)],
                (np.array([0.0]), np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]])),
                Transform(),
            ),
            ValueError,
            r"t must have shape \(4,\)",
        ),
        (
            lambda m: m.insert_frames(
                [(np.zeros((4, 3)), np.zeros(4), np.nan)],
                (np.array([0.0]), np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]])),
                Transform(),
            ),
            ValueError,
            "t_origin must be finite",
        ),
        (
            lambda m: m.insert_frames(
                [(np.zeros((4, 3)), np.zeros(4))],
                (np.array([0.0]), np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]])),
                Transform(),
            ),
            ValueError,
            r"frames\[0\] must be a tuple",
        ),
        (
            lambda m: m.insert_frames([], (np.array([0.0]), np.zeros((1, 3)), np.array([[1.0, 0, 0, 0]])), "T"),
            TypeError,
            "T_BL must be a cufund.geometry.Transform",
        ),
        (
            lambda m: m.insert_frames([], (np.zeros(0), np.zeros((0, 3)), np.zeros((0, 4))), Transform()),
            ValueError,
            "knots_t must be a non-empty",
        ),
    ],
)
def test_batched_inserts_reject_bad_input_clearly(call, error, message):
    m = make_map()
    before = m.log_odds()
    with pytest.raises(error, match=message):
        call(m)
    np.testing.assert_array_equal(m.log_odds(), before)


def test_merge_beams_must_be_a_bool():
    from cufund import ConfigError

    with pytest.raises(ConfigError, match="merge_beams must be a bool"):
        esdf.EsdfMapParams(resolution=0.1, size=(1.0, 1.0, 1.0), merge_beams=1)


def _replay_bus(mapper, poses, clouds):
    """cufund's Bus with the mapper subscribed and the stamped messages ``(t, message)`` in flight, each to
    become visible at its t (``bus.release(now_ns)`` makes those due visible)."""
    from cufund.core.bus import Bus
    from cufund.core.messages import Topics

    bus = Bus(record=[Topics.ESDF_MAP])
    mapper.setup(bus)
    for topic, items in ((mapper.active_state_topic, poses), (mapper.cloud_topic, clouds)):
        for t, message in items:
            bus.publish(topic, message, latency_ns=round(t * 1e9))
    return bus


def test_the_mapper_stepped_slowly_batches_frames_into_the_same_map(rng):
    """Stepped at 2 Hz the mapper inserts the 10 frames that arrived by t = 0.5 s in one call; the map equals the one built
    stepping at the LiDAR's 20 Hz, one frame per call (the same pose stream and frames)."""
    from cufund.core.messages import Odometry, PointCloud, Topics

    T_BL = Transform((0.05, 0.0, 0.1), (0.999, 0.0, 0.04, 0.0))
    poses = []
    for k in range(241):  # 200 Hz, moving and turning
        t = 0.005 * k
        yaw = 0.3 * t
        poses.append(
            (
                t,
                Odometry(
                    t=t,
                    p_W=np.array([0.3 * t, 0.1 * np.sin(t), 0.6]),
                    v_W=np.zeros(3),
                    q_WB=np.array([np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]),
                    w_B=np.zeros(3),
                ),
            )
        )
    clouds = []
    for f in range(11):  # 20 Hz frames of 0.05 s, published at their end
        n = 1500
        dt = np.sort(rng.uniform(0.0, 0.05, n))
        points_L = (rng.normal(size=(n, 3)) * [1.2, 1.0, 0.4]).astype(np.float32)
        cloud = PointCloud(
            t=0.05 * f,
            dt=dt,
            points_L=points_L,
            ranges=np.linalg.norm(points_L, axis=1),
            intensity=np.zeros(n),
            channel=np.zeros(n, dtype=np.int32),
            frame=f,
        )
        clouds.append((0.05 * f + 0.05, cloud))
    mappers = []
    for rate in (20.0, 2.0):
        params = esdf.EsdfMapParams(
            resolution=0.05, size=(4.0, 4.0, 2.0), origin_W=(-2.0, -2.0, -0.5), max_range=2.0, merge_beams=True
        )
        mapper = esdf.EsdfMapper(params, T_BL=T_BL, rate_hz=rate, cloud_topic="/clouds")
        bus = _replay_bus(mapper, poses, clouds)
        for k in range(int(1.2 * rate) + 1):
            bus.release(round(k / rate * 1e9))
            mapper.integrate(k / rate, bus)
        mappers.append((mapper, bus.recorded(Topics.ESDF_MAP)))
    (fast, fast_published), (slow, slow_published) = mappers
    assert fast.frames == slow.frames == 11
    assert [u.frames for u in slow_published] == [10, 11] and len(fast_published) >= 9
    np.testing.assert_array_equal(fast.map.log_odds(), slow.map.log_odds())
    np.testing.assert_array_equal(fast.map.distances(), slow.map.distances())
    assert slow.map.occupied().sum() > 100
