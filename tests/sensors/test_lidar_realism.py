"""The LiDAR's realism terms (issue 31) against independent references: range noise growing with range and
incidence (a chi-square bound on a plane at several ranges and tilts), reflectivity- and incidence-dependent
detection (counts against the detection-probability formula), mixed pixels (only at depth edges, between the two
surfaces), timestamp jitter, intensity noise, the LiDAR-IMU time offset; and, with every term off, frames bit for
bit what they were before the terms existed."""

import hashlib

import numpy as np
import pytest
from scipy import stats

import cufund
from cufund import sensors as L
from cufund.geometry import yaw_quaternion
from cufund.worlds import primitives

COS_85 = np.cos(np.deg2rad(85.0))


def static_pose(p=(0.0, 0.0, 0.0)):
    return lambda t: (np.array(p, float), np.array([1.0, 0.0, 0.0, 0.0]))


def add_slab(world, size, position, yaw=0.0, reflectivity=0.8, label="slab"):
    return world.add_mesh(*primitives.box(size), label, (0.7, 0.7, 0.7), position, yaw, reflectivity)


def tilted_wall(distance, tilt_deg, reflectivity=0.8):
    """A 400 m x 400 m wall whose face passes through (distance, 0, 0) with normal (cos tilt, sin tilt, 0)."""
    a = np.deg2rad(tilt_deg)
    n = np.array([np.cos(a), np.sin(a), 0.0])
    w = cufund.World("wall")
    add_slab(w, (0.2, 400.0, 400.0), np.array([distance, 0.0, 0.0]) + 0.1 * n, a, reflectivity, "wall")
    return w, n


def truth_geometry(truth, normal):
    """True range and |cos incidence| of each return of a LiDAR at the origin, from the noise-free hits."""
    p = truth.points_W.astype(np.float64)
    r = np.linalg.norm(p, axis=1)
    return r, np.abs(p @ normal) / r


def chi2_bounds(n, alpha=1e-6):
    return stats.chi2.ppf(alpha, n), stats.chi2.ppf(1.0 - alpha, n)


# --- range noise ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("distance", [2.0, 10.0, 30.0])
@pytest.mark.parametrize("tilt_deg", [0.0, 45.0, 70.0])
def test_range_noise_grows_with_range_and_incidence_as_specified(distance, tilt_deg):
    std, per_m, inc = 0.01, 0.002, 0.5
    world, n = tilted_wall(distance, tilt_deg)
    params = L.LidarParams(
        range_max=60.0, range_noise_std=std, range_noise_per_m=per_m, incidence_noise=inc, seed=int(distance + tilt_deg)
    )
    pc, truth = L.Lidar(L.vlp16(), params).scan_with_truth(world, static_pose(), 0.0)
    r, c = truth_geometry(truth, n)
    assert len(r) > 2000
    # The contract's sigma(r, theta), written out here from its definition.
    sigma = (std + per_m * r) * (1.0 + inc * (1.0 / np.maximum(c, COS_85) - 1.0))
    e = (pc.ranges - r) / sigma
    lo, hi = chi2_bounds(len(e))
    assert lo < np.sum(e**2) < hi
    assert abs(np.mean(e)) < 5.0 / np.sqrt(len(e))
    # Per range bin, the measured std over the specified one (each bin a chi-square bound of its own).
    for idx in np.array_split(np.argsort(r), 5):
        lo, hi = chi2_bounds(len(idx))
        assert lo < np.sum(e[idx] ** 2) < hi, (r[idx].min(), r[idx].max())
    # The bound has the power to see a missing term: without the incidence factor, or the range-proportional part.
    lo, hi = chi2_bounds(len(e))
    wrong = []
    if tilt_deg >= 45.0:
        wrong.append((std + per_m * r) * np.ones_like(c))
    if distance >= 10.0:
        wrong.append(std * (1.0 + inc * (1.0 / np.maximum(c, COS_85) - 1.0)))
    for w in wrong:
        assert not lo < np.sum(((pc.ranges - r) / w) ** 2) < hi


def test_range_noise_without_a_constant_term_grows_from_zero():
    world, n = tilted_wall(5.0, 0.0)
    pc, truth = L.Lidar(L.vlp16(), L.LidarParams(range_max=60.0, range_noise_per_m=0.003, seed=4)).scan_with_truth(
        world, static_pose(), 0.0
    )
    r, _ = truth_geometry(truth, n)
    e = (pc.ranges - r) / (0.003 * r)
    lo, hi = chi2_bounds(len(e))
    assert lo < np.sum(e**2) < hi


# --- detection probability --------------------------------------------------------------------------------------


def detection_probability(r, rho, c, r10, softness):
    """The contract: 1 up to r_max = r10 sqrt(rho cos / 0.1), 0 past r_max (1 + softness), a smoothstep between."""
    r_max = r10 * np.sqrt(rho * c / 0.1)
    x = np.clip((r - r_max) / (softness * r_max), 0.0, 1.0)
    return 1.0 - x * x * (3.0 - 2.0 * x)


@pytest.mark.parametrize("reflectivity", [0.05, 0.2, 0.8])
def test_detection_fraction_follows_reflectivity_incidence_and_range(reflectivity):
    """A wall of known reflectivity 4 m ahead: range and incidence both change along each channel. Four frames
    of an OS1-64 (the same rays, fresh draws) sample the fall from certain to no detection a few thousand times."""
    d, r10, soft = 4.0, 12.0, 0.3
    w, _ = tilted_wall(d, 0.0, reflectivity)
    pose = static_pose()
    clean, clean_truth = L.Lidar(L.os1_64(), L.LidarParams(range_max=150.0)).scan_with_truth(w, pose, 0.0)
    r = clean.ranges
    c = d / r  # a wall facing the sensor: |cos incidence| = distance / range
    p = detection_probability(r, reflectivity, c, r10, soft)
    mid = (p > 0.0) & (p < 1.0)
    lid = L.Lidar(L.os1_64(), L.LidarParams(range_max=150.0, max_range_at_10pct=r10, detection_softness=soft, seed=11))
    kept = []
    for k in range(4):
        got, got_truth = lid.scan_with_truth(w, pose, 0.1 * k)
        # Each return of a ray, keyed by (firing time, channel): the detected ones are a subset of the clean ones.
        key = lambda pc: pc.dt * 1e6 + pc.channel / 100.0  # noqa: E731
        kept.append(np.isin(key(clean), key(got)))
        assert kept[-1].sum() == len(got)
        assert np.all(kept[-1][p == 1.0]) and not np.any(kept[-1][p == 0.0])
        np.testing.assert_array_equal(got_truth.object_ids, clean_truth.object_ids[kept[-1]])
    kept_mid, p_mid = np.concatenate([kk[mid] for kk in kept]), np.tile(p[mid], len(kept))
    assert len(p_mid) > 2000  # the transition is sampled
    expected, var = p_mid.sum(), (p_mid * (1.0 - p_mid)).sum()
    assert abs(kept_mid.sum() - expected) < 5.0 * np.sqrt(var)
    # Binned by probability, the observed counts follow it (a chi-square over ten bins): a wrong r_max, width or
    # shape of the fall moves them.
    edges = np.linspace(0.0, 1.0, 11)
    which = np.clip(np.digitize(p_mid, edges) - 1, 0, 9)
    chi2 = 0.0
    for b in range(10):
        sel = which == b
        if sel.sum():
            chi2 += (kept_mid[sel].sum() - p_mid[sel].sum()) ** 2 / max((p_mid[sel] * (1 - p_mid[sel])).sum(), 1e-9)
    assert chi2 < stats.chi2.ppf(1.0 - 1e-6, 10)


def test_detection_range_scales_with_reflectivity_on_walls_at_normal_incidence():
    """Walls straight ahead at 10 m of reflectivity 0.1 and 0.4: with a 9 m detection range at 10 %, the first is
    beyond r_max (1 + softness) and returns nothing near the normal, the second (r_max = 18 m) everything there."""
    for rho, expect in [(0.1, 0.0), (0.4, 1.0)]:
        w, n = tilted_wall(10.0, 0.0, rho)
        params = L.LidarParams(range_max=100.0, max_range_at_10pct=9.0, detection_softness=0.05, seed=1)
        clean = L.Lidar(L.vlp16(), L.LidarParams(range_max=100.0)).scan(w, static_pose(), 0.0)
        got = L.Lidar(L.vlp16(), params).scan(w, static_pose(), 0.0)
        near = lambda pc: np.sum(pc.ranges < 10.2)  # noqa: E731, rays within ~11 deg of the normal
        assert near(clean) > 100 and near(got) == expect * near(clean)


# --- mixed pixels -----------------------------------------------------------------------------------------------


def room_with_pillar():
    """A closed 30 m room (every ray hits) with four pillars 3 to 6 m from the sensor: depth edges of ~10 m."""
    w = cufund.World("room")
    for pos, size in [
        ((15.1, 0, 0), (0.2, 30.4, 30.4)),
        ((-15.1, 0, 0), (0.2, 30.4, 30.4)),
        ((0, 15.1, 0), (30.4, 0.2, 30.4)),
        ((0, -15.1, 0), (30.4, 0.2, 30.4)),
        ((0, 0, 15.1), (30.4, 30.4, 0.2)),
        ((0, 0, -15.1), (30.4, 30.4, 0.2)),
    ]:
        add_slab(w, size, pos, label="wall")
    for x, y in [(3.25, 0.0), (0.0, 4.0), (-5.0, 2.0), (2.0, -6.0)]:
        add_slab(w, (0.5, 0.5, 30.0), (x, y, 0.0), label="pillar")
    return w


def channel_neighbours(channel):
    """For each ray (all rays returned, in firing order), the previous and next ray of its channel (-1: none)."""
    prev, nxt = np.full(len(channel), -1), np.full(len(channel), -1)
    for ch in np.unique(channel):
        idx = np.nonzero(channel == ch)[0]
        prev[idx[1:]], nxt[idx[:-1]] = idx[:-1], idx[1:]
    return prev, nxt


@pytest.mark.parametrize("probability", [1.0, 0.3])
def test_mixed_pixels_only_at_depth_edges_and_between_the_two_surfaces(probability):
    w, edge = room_with_pillar(), 0.3
    clean = L.Lidar(L.vlp16(), L.LidarParams(range_max=100.0)).scan(w, static_pose(), 0.0)
    params = L.LidarParams(range_max=100.0, mixed_pixel_probability=probability, mixed_pixel_edge_m=edge, seed=2)
    got = L.Lidar(L.vlp16(), params).scan(w, static_pose(), 0.0)
    assert len(clean) == len(got) == 16 * 1800  # a closed room: every ray returns, in ray order
    np.testing.assert_array_equal(got.channel, clean.channel)
    r0, r = clean.ranges, got.ranges
    prev, nxt = channel_neighbours(clean.channel)
    jump = np.zeros((len(r0), 2))
    for k, nb in enumerate((prev, nxt)):
        ok = nb >= 0
        jump[ok, k] = r0[nb[ok]] - r0[ok]
    at_edge = np.any(np.abs(jump) > edge, axis=1)
    assert 100 < at_edge.sum() < 0.05 * len(r0)
    np.testing.assert_array_equal(r[~at_edge], r0[~at_edge])  # away from an edge nothing moves
    moved = r != r0
    assert not np.any(moved & ~at_edge)
    # Mixed returns lie between their own surface and the farthest-apart neighbour across the edge.
    other = r0 + np.where(np.abs(jump[:, 0]) >= np.abs(jump[:, 1]), jump[:, 0], jump[:, 1])
    lo, hi = np.minimum(r0, other), np.maximum(r0, other)
    assert np.all((r[moved] >= lo[moved]) & (r[moved] <= hi[moved]))
    n_edge, n_mixed = at_edge.sum(), moved.sum()
    assert abs(n_mixed - probability * n_edge) <= 5.0 * np.sqrt(n_edge * probability * (1 - probability)) + 1
    # The mix is uniform along the ray between the two surfaces.
    u = (r[moved] - r0[moved]) / (other[moved] - r0[moved])
    assert stats.kstest(u, "uniform").pvalue > 1e-4
    # The points follow their ranges along the same rays.
    d0 = clean.points_L / np.linalg.norm(clean.points_L, axis=1, keepdims=True)
    np.testing.assert_allclose(got.points_L, d0 * r[:, None], atol=2e-5)


# --- timestamps, intensity ---------------------------------------------------------------------------------------


def test_timestamp_jitter_has_the_given_std_and_keeps_the_points_in_their_firing_slots():
    w = room_with_pillar()
    sigma = 2e-6
    ref = L.Lidar(L.mid360(), L.LidarParams(range_max=100.0))
    lid = L.Lidar(L.mid360(), L.LidarParams(range_max=100.0, timestamp_jitter_s=sigma, seed=5))
    e = []
    for k in range(5):
        clean, clean_truth = ref.scan_with_truth(w, static_pose(), 0.1 * k)
        got, got_truth = lid.scan_with_truth(w, static_pose(), 0.1 * k)
        # Only the reported times change: the rays were cast at their true times, in the same order.
        np.testing.assert_array_equal(got.points_L, clean.points_L)
        np.testing.assert_array_equal(got.channel, clean.channel)
        np.testing.assert_array_equal(got_truth.points_W, clean_truth.points_W)
        assert got.dt.min() >= 0.0 and got.dt.max() < lid.period
        inner = (clean.dt > 10 * sigma) & (clean.dt < lid.period - 10 * sigma)  # away from the clamps
        e.append((got.dt - clean.dt)[inner] / sigma)
    e = np.concatenate(e)
    lo, hi = chi2_bounds(len(e))
    assert lo < np.sum(e**2) < hi
    assert abs(e.mean()) < 5.0 / np.sqrt(len(e))


@pytest.mark.parametrize("r10", [np.inf, 25.0])
def test_intensity_noise_is_relative_and_grows_towards_the_detection_range(r10):
    world, n = tilted_wall(8.0, 30.0, reflectivity=0.5)
    clean, truth = L.Lidar(L.vlp16(), L.LidarParams(range_max=60.0)).scan_with_truth(world, static_pose(), 0.0)
    params = L.LidarParams(range_max=60.0, intensity_noise=0.05, max_range_at_10pct=r10, detection_softness=0.2)
    got, got_truth = L.Lidar(L.vlp16(), params).scan_with_truth(world, static_pose(), 0.0)
    r, c = truth_geometry(got_truth, n)
    mean = 0.5 * c  # reflectivity x |cos incidence|, the intensity without noise
    keep = np.isin(clean.dt * 1e6 + clean.channel / 100.0, got.dt * 1e6 + got.channel / 100.0)
    np.testing.assert_allclose(mean, clean.intensity[keep], rtol=1e-5)
    r_max = r10 * np.sqrt(0.5 * c / 0.1)
    s = 0.05 * (1.0 + (r / r_max) ** 2)
    unclipped = (got.intensity > 0.0) & (got.intensity < 1.0)
    assert unclipped.mean() > 0.99
    e = (got.intensity / mean - 1.0)[unclipped] / s[unclipped]
    lo, hi = chi2_bounds(len(e))
    assert lo < np.sum(e**2) < hi
    if np.isfinite(r10):
        assert s.max() > 1.5 * s.min()  # the frame spans weak and strong returns


def test_time_offset_shifts_the_stamp_exactly_and_nothing_else():
    w = cufund.worlds.load("imav2025_tunnel")
    pose = lambda t: (np.array([1.0 + 0.5 * t, 0.2, 1.0]), yaw_quaternion(0.3 * t))  # noqa: E731
    a, a_truth = L.Lidar(L.mid360(), L.mid360_params(seed=3)).scan_with_truth(w, pose, 1.3)
    for offset in (0.004, -0.0025):
        b, b_truth = L.Lidar(L.mid360(), L.mid360_params(seed=3, time_offset_s=offset)).scan_with_truth(w, pose, 1.3)
        assert b.t == 1.3 + offset and b_truth.t == 1.3 == a.t
        for f in ("dt", "points_L", "ranges", "intensity", "channel"):
            np.testing.assert_array_equal(getattr(b, f), getattr(a, f), err_msg=f)
        np.testing.assert_array_equal(b_truth.points_W, a_truth.points_W)


# --- off means unchanged; the random stream ----------------------------------------------------------------------


def _frames_hash():
    """SHA-256 of LiDAR frames of the tunnel, moving, with the terms that existed before issue 31."""
    world = cufund.worlds.load("imav2025_tunnel")
    pose = lambda t: (np.array([1.0 + 0.5 * t, 0.2, 1.0]), yaw_quaternion(0.3 * t))  # noqa: E731
    h = hashlib.sha256()
    for pat, params in [
        (L.mid360(), L.mid360_params(seed=3)),
        (L.mid360(), L.LidarParams(range_noise_std=0.01, dropout=0.1, seed=5)),
        (L.vlp16(), L.LidarParams(seed=1)),
    ]:
        lid = L.Lidar(pat, params)
        for k in range(3):
            for target in (world, world.raycast_scene):
                pc, tr = lid.scan_with_truth(target, pose, 0.1 * k)
                for a in (pc.dt, pc.points_L, pc.ranges, pc.intensity, pc.channel, tr.points_W, tr.object_ids):
                    h.update(np.ascontiguousarray(a).tobytes())
                    h.update(str(a.dtype).encode())
                h.update(repr((pc.t, pc.frame, tr.t)).encode())
    return h.hexdigest()


def test_frames_without_the_new_terms_follow_the_old_draws_and_range_model():
    """Portable: the frame of a LiDAR with the pre-issue-31 terms only equals the one-call kernel given the draws
    the LiDAR always made (dropout uniforms, then range noise in metres) through its old arguments."""
    world = cufund.worlds.load("imav2025_tunnel")
    pattern = L.mid360()
    params = L.mid360_params(dropout=0.2, seed=9)
    lid = L.Lidar(pattern, params)
    pc, truth = lid.scan_with_truth(world, static_pose((1.0, 0.0, 1.0)), 0.5)
    rng = np.random.default_rng(9)
    rays = pattern.frame(0)
    n = len(rays.t)
    keep = rng.random(n)
    noise = rng.standard_normal(n) * params.range_noise_std
    assert lid._rng.bit_generator.state == rng.bit_generator.state  # no other draw was made
    knots = 0.5 + np.linspace(0.0, pattern.period, params.pose_samples)
    p_k, q_k = np.tile([1.0, 0.0, 1.0], (len(knots), 1)), np.tile([1.0, 0.0, 0.0, 0.0], (len(knots), 1))
    old = cufund._core.lidar.scan_frame(
        world.raycast_scene, rays.directions(), rays.t, rays.channel, 0.5, knots, p_k, q_k,
        params.range_min, params.range_max, noise, keep, params.dropout, world.reflectivities(), 0,
    )  # fmt: skip
    for f in ("dt", "points_L", "ranges", "intensity", "channel"):
        np.testing.assert_array_equal(getattr(pc, f), old[f], err_msg=f)
    np.testing.assert_array_equal(truth.points_W, old["points_W"])
    assert pc.t == 0.5


def test_a_new_term_draws_after_the_old_ones_and_only_when_on():
    w = cufund.worlds.load("imav2025_tunnel")
    base = dict(range_noise_std=0.02, dropout=0.2, seed=4)
    a = L.Lidar(L.mid360(), L.LidarParams(**base)).scan(w, static_pose((1.0, 0.0, 1.0)), 0.0)
    b = L.Lidar(L.mid360(), L.LidarParams(**base, timestamp_jitter_s=1e-6, intensity_noise=0.1)).scan(
        w, static_pose((1.0, 0.0, 1.0)), 0.0
    )
    np.testing.assert_array_equal(a.ranges, b.ranges)  # the dropout and range noise draws are the same
    assert not np.array_equal(a.dt, b.dt) and not np.array_equal(a.intensity, b.intensity)
    off = dict(
        range_noise_per_m=0.0,
        incidence_noise=0.0,
        max_range_at_10pct=np.inf,
        mixed_pixel_probability=0.0,
        timestamp_jitter_s=0.0,
        intensity_noise=0.0,
        time_offset_s=0.0,
    )
    c = L.Lidar(L.mid360(), L.LidarParams(**base, **off)).scan(w, static_pose((1.0, 0.0, 1.0)), 0.0)
    np.testing.assert_array_equal(a.points_L, c.points_L)
    np.testing.assert_array_equal(a.intensity, c.intensity)


def test_all_terms_on_are_deterministic_per_seed():
    w = cufund.worlds.load("imav2025_tunnel")
    on = dict(
        range_noise_per_m=0.001,
        incidence_noise=0.5,
        max_range_at_10pct=6.0,
        mixed_pixel_probability=0.5,
        timestamp_jitter_s=1e-6,
        intensity_noise=0.1,
        time_offset_s=0.002,
    )
    scans = [
        L.Lidar(L.mid360(), L.mid360_params(seed=s, **on)).scan(w, static_pose((1.0, 0.0, 1.0)), 0.0) for s in (1, 1, 2)
    ]
    np.testing.assert_array_equal(scans[0].points_L, scans[1].points_L)
    np.testing.assert_array_equal(scans[0].dt, scans[1].dt)
    assert len(scans[0]) != len(scans[2]) or not np.array_equal(scans[0].ranges, scans[2].ranges)


# --- bad input ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "field, value",
    [
        ("range_noise_per_m", -0.001),
        ("range_noise_per_m", np.nan),
        ("incidence_noise", -1.0),
        ("max_range_at_10pct", 0.0),
        ("max_range_at_10pct", -5.0),
        ("max_range_at_10pct", np.nan),
        ("detection_softness", -0.1),
        ("mixed_pixel_probability", 1.5),
        ("mixed_pixel_edge_m", 0.0),
        ("timestamp_jitter_s", -1e-6),
        ("intensity_noise", np.inf),
        ("time_offset_s", np.inf),
        ("time_offset_s", "3 ms"),
    ],
)
def test_bad_realism_fields_raise_naming_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        L.LidarParams(**{field: value})


def test_scan_frame_checks_the_realism_arguments():
    world = cufund.worlds.load("imav2025_tunnel")
    rays = L.mid360().frame(0)
    n = len(rays.t)
    base = dict(
        scene=world.raycast_scene,
        d_L=rays.directions(),
        t=rays.t,
        channel=rays.channel,
        t0=0.0,
        knot_t=np.array([0.0, 0.1]),
        knot_p=np.tile([-2.5, 0.0, 1.0], (2, 1)),
        knot_q=np.tile([1.0, 0, 0, 0], (2, 1)),
        range_min=0.1,
        range_max=40.0,
    )
    for change, message in [
        ({"noise": np.zeros(n), "noise_z": np.zeros(n)}, "noise and noise_z"),
        ({"noise_z": np.zeros(n - 1)}, "noise_z"),
        ({"mixed_draw": np.zeros(n)}, r"mixed_draw must have shape \(\d+, 2\)"),
        ({"detect_draw": np.full(n, np.nan)}, "detect_draw"),
        ({"max_range_at_10pct": 0.0}, "max_range_at_10pct"),
        ({"range_noise_per_m": -1.0}, "range_noise_per_m"),
        ({"mixed_pixel_probability": 2.0}, "mixed_pixel_probability"),
        ({"dt_max": np.nan}, "dt_max"),
    ]:
        with pytest.raises(ValueError, match=message):
            cufund._core.lidar.scan_frame(**{**base, **change})
