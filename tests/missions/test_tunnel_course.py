"""Seeded tunnel courses: reproducible, within their bounds, and flyable — the check's path verified
against Open3D's exact distance to the course's triangles."""

from __future__ import annotations

import math

import numpy as np
import pytest

import cufund.worlds as worlds
from cufund.missions.tunnel_course import TunnelCourseParams, tunnel_course, tunnel_course_layout

o3d = pytest.importorskip("open3d")


def _distance(world):
    scene = o3d.t.geometry.RaycastingScene()
    for o in world.objects:
        scene.add_triangles(o.vertices.astype(np.float32), o.triangles.astype(np.uint32))
    return lambda p: scene.compute_distance(np.asarray(p, np.float32).reshape(-1, 3)).numpy().astype(float)


@pytest.fixture(scope="module", params=[0, 1, 2])
def course(request):
    return tunnel_course_layout(request.param)


def test_same_seed_same_course_and_seeds_differ():
    a, b, c = tunnel_course_layout(4), tunnel_course_layout(4), tunnel_course_layout(5)
    assert a.frames == b.frames
    for oa, ob in zip(a.world.objects, b.world.objects, strict=True):
        np.testing.assert_array_equal(oa.vertices, ob.vertices)
    assert a.frames != c.frames
    assert len(worlds.load("tunnel_course", seed=4).objects) == len(a.world.objects)
    np.testing.assert_array_equal(tunnel_course(4).bounds(), a.world.bounds())


def test_frames_within_their_bounds(course):
    p = TunnelCourseParams()
    f = course.frames
    assert len(f) == p.n_frames
    assert all((fr.width, fr.height) in p.openings for fr in f)
    assert f[0].centre_W[0] == 0.0 and abs(f[0].centre_W[1]) <= p.entrance_offset
    assert abs(math.degrees(f[0].yaw)) <= p.entrance_yaw
    for a, b in zip(f[:-1], f[1:], strict=True):
        d = np.subtract(b.centre_W, a.centre_W)
        ahead = d[:2] @ a.axis_W[:2]
        side = d[0] * -math.sin(a.yaw) + d[1] * math.cos(a.yaw)
        assert p.spacing[0] - 1e-9 <= ahead <= p.spacing[1] + 1e-9
        assert abs(side) <= p.lateral_offset + 1e-9
        assert abs(math.degrees(b.yaw - a.yaw)) <= p.yaw_change + 1e-9
        assert abs(d[2]) <= p.vertical_offset + 1e-9 or b.centre_W[2] == b.height / 2 + p.bar  # raised off the floor
    # The arena encloses everything: the world's bounds are the arena's outer walls.
    lo, hi = course.world.bounds()
    np.testing.assert_allclose(lo, [-p.arena_lead - 0.1, -p.arena[1] / 2 - 0.1, -0.1], atol=1e-9)
    np.testing.assert_allclose(hi, [p.arena[0] - p.arena_lead + 0.1, p.arena[1] / 2 + 0.1, p.arena[2] + 0.1], atol=1e-9)


def test_flyability_path_clears_the_triangles_and_threads_every_opening(course):
    r = TunnelCourseParams().vehicle_radius
    path = course.path_W
    np.testing.assert_array_equal(path[0], course.entry_W)
    np.testing.assert_array_equal(path[-1], course.exit_W)
    dense = np.vstack([a + np.linspace(0, 1, 200)[:, None] * (b - a) for a, b in zip(path[:-1], path[1:], strict=True)])
    assert _distance(course.world)(dense).min() >= r - 1e-5
    for fr in course.frames:
        # Crossing the frame's plane (signed distance along its axis changes sign) inside the opening.
        s = (dense - fr.centre_W) @ fr.axis_W
        k = np.flatnonzero(np.sign(s[:-1]) != np.sign(s[1:]))
        assert k.size >= 1
        across = np.array([-math.sin(fr.yaw), math.cos(fr.yaw), 0.0])
        hits = [dense[i] - fr.centre_W for i in k]
        assert any(abs(h @ across) <= fr.width / 2 - r + 0.01 and abs(h[2]) <= fr.height / 2 - r + 0.01 for h in hits)


def test_unflyable_bounds_raise_a_clear_error():
    with pytest.raises(ValueError, match=r"no flyable tunnel course for seed 0 in 3 draws"):
        tunnel_course_layout(0, TunnelCourseParams(openings=((0.5, 0.5),), vehicle_radius=0.26, max_attempts=3))
    with pytest.raises(ValueError, match="openings must be"):
        TunnelCourseParams(openings=())
    with pytest.raises(ValueError, match="spacing must be two finite numbers"):
        TunnelCourseParams(spacing=(2.0, 1.0))
    with pytest.raises(ValueError, match="seed must be an integer >= 0"):
        tunnel_course_layout(-1)
