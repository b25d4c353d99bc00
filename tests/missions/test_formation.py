"""Formation flight references (cufund.missions.formation): a virtual structure stays rigid (every pair at its
offsets' distance at every instant) and its slots sit at the path point plus the turned offset; a leader-follower's
follower is at the leader's earlier position plus the offset turned by the leader's course, written out by hand."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from cufund.missions.deconfliction import Trajectory
from cufund.missions.formation import formation_offsets, leader_follower, virtual_structure

PATH = [(0.0, 0.0, 5.0), (10.0, 0.0, 5.0), (10.0, 10.0, 5.0)]


def test_offsets_of_the_shapes():
    line = formation_offsets("line", 3, 2.0)
    np.testing.assert_allclose(line, [[0, 2, 0], [0, 0, 0], [0, -2, 0]])
    np.testing.assert_allclose(formation_offsets("column", 3, 2.0), [[0, 0, 0], [-2, 0, 0], [-4, 0, 0]])
    wedge = formation_offsets("wedge", 5, 2.0)
    assert np.all(wedge[0] == 0)
    np.testing.assert_allclose(np.linalg.norm(wedge[1:], axis=1), [2, 2, 4, 4])
    np.testing.assert_allclose(np.degrees(np.arctan2(wedge[1:, 1], -wedge[1:, 0])), [30, -30, 30, -30])
    with pytest.raises(ValueError, match="shape"):
        formation_offsets("circle", 3, 1.0)


def test_a_virtual_structure_is_rigid_and_follows_the_path():
    offsets = formation_offsets("wedge", 3, 2.0)
    slots = virtual_structure(PATH, offsets, speed=1.0, yaw_rate=0.5)
    assert all(np.array_equal(s.t, slots[0].t) for s in slots)
    for i, j in itertools.combinations(range(3), 2):
        dist = np.linalg.norm(slots[i].p - slots[j].p, axis=1)
        np.testing.assert_allclose(dist, np.linalg.norm(offsets[i] - offsets[j]), atol=1e-12)
    # on the first leg (heading east) each slot is the path point plus its offset; on the second (north) the
    # offset turned by 90 degrees: (x, y) -> (-y, x)
    lead = slots[0]
    k1 = np.argmin(np.abs(lead.p[:, 0] - 5.0) + np.abs(lead.p[:, 1]))
    np.testing.assert_allclose(slots[1].p[k1], lead.p[k1] + offsets[1], atol=1e-12)
    k2 = np.argmin(np.abs(lead.p[:, 0] - 10.0) + np.abs(lead.p[:, 1] - 5.0))
    turned = np.array([-offsets[2][1], offsets[2][0], 0.0])
    np.testing.assert_allclose(slots[2].p[k2], lead.p[k2] + turned, atol=1e-12)
    # the turn at the corner takes (pi / 2) / yaw_rate on the spot
    at_corner = np.all(np.abs(lead.p - PATH[1]) < 1e-12, axis=1)
    assert np.ptp(lead.t[at_corner]) == pytest.approx((math.pi / 2) / 0.5, abs=0.06)


def test_leader_follower_offsets_in_the_leaders_frame_with_a_delay():
    leader = Trajectory.from_path(PATH, 1.0)
    offsets = np.array([[-2.0, 1.0, 0.0], [-2.0, -1.0, 0.5]])
    f = leader_follower(leader, offsets, delay=[0.0, 1.0])
    # t = 5 s: the leader at (5, 0, 5) heading east
    np.testing.assert_allclose(f[0].at(5.0), [3.0, 1.0, 5.0], atol=1e-9)
    # the second follower 1 s behind: at 6 s where the leader was at 5 s
    np.testing.assert_allclose(f[1].at(6.0), [3.0, -1.0, 5.5], atol=1e-9)
    # t = 15 s: the leader at (10, 5, 5) heading north: forward is +y, left is -x
    np.testing.assert_allclose(f[0].at(15.0), [9.0, 3.0, 5.0], atol=1e-9)
    np.testing.assert_allclose(f[1].at(16.0), [11.0, 3.0, 5.5], atol=1e-9)
    # a column on the leader's own track: zero offset, delayed
    trail = leader_follower(leader, np.zeros((1, 3)), delay=2.0)[0]
    for t in (3.0, 9.0, 14.0, 21.0):
        np.testing.assert_allclose(trail.at(t + 2.0), leader.at(t), atol=1e-9)
