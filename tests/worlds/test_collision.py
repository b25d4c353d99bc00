"""Vehicle-world collisions (Bullet): touching, penetrating and near-miss cases against analytic gaps."""

import numpy as np
import pytest

import cufund
from cufund.worlds import CollisionChecker

IDENTITY = (1.0, 0.0, 0.0, 0.0)
CU_ASTRO = (0.216, 0.216, 0.095)  # paper §3


def test_cu_astro_box_in_the_tunnel_touches_a_frame_post_only_when_it_reaches_it():
    w = cufund.worlds.load("imav2025_tunnel")
    cc = CollisionChecker(w, box_size=CU_ASTRO)
    assert cc.check((-1.0, 0.0, 0.55), IDENTITY) is None  # in front of the tunnel, centred
    assert cc.check((1.0, 0.0, 0.55), IDENTITY) is None  # inside, centred: 0.142 m to each post
    # The posts' inner faces are at y = ±0.25; the box reaches y ± 0.108.
    c = cc.check((0.0, 0.25 - 0.108 + 0.004, 0.55), IDENTITY)
    assert c is not None and c.label == "tunnel_frame"
    assert c.distance == pytest.approx(-0.004, abs=1e-3)
    np.testing.assert_allclose(c.normal_W, [0.0, -1.0, 0.0], atol=1e-3)  # EPA normal
    assert c.point_W[1] == pytest.approx(0.25, abs=1e-3)
    near = (0.0, 0.25 - 0.108 - 0.004, 0.55)
    assert cc.check(near, IDENTITY) is None
    c = cc.check(near, IDENTITY, margin=0.01)
    assert c is not None and c.distance == pytest.approx(0.004, abs=1e-3)


def test_ground_contact_and_yaw_matter():
    w = cufund.worlds.load("empty")
    cc = CollisionChecker(w, box_size=(0.4, 0.2, 0.1))
    assert cc.check((0.0, 0.0, 0.051), IDENTITY) is None
    c = cc.check((0.0, 0.0, 0.049), IDENTITY)
    assert c is not None and c.label == "ground" and c.distance == pytest.approx(-0.001, abs=5e-4)
    # Pitched 90° about y, the 0.4 m edge points down: it reaches 0.2 m below the centre.
    q_pitch = (np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0)
    assert cc.check((0.0, 0.0, 0.15), q_pitch) is not None
    assert cc.check((0.0, 0.0, 0.21), q_pitch) is None


def test_sphere_vehicle_against_forest_trees():
    w = cufund.worlds.load("forest", seed=4, n_trees=10)
    tree = next(o for o in w.objects if o.label == "tree")
    centre = tree.vertices[:, :2].mean(axis=0)
    r_tree = np.max(np.linalg.norm(tree.vertices[:, :2] - centre, axis=1))  # vertex radius
    cc = CollisionChecker(w, radius=0.3)
    # Approach along a vertex direction, where the 12-gon's radius is exactly r_tree.
    d = (tree.vertices[0, :2] - centre) / np.linalg.norm(tree.vertices[0, :2] - centre)
    hit = cc.check((*(centre + d * (r_tree + 0.29)), 1.0), IDENTITY)
    assert hit is not None and hit.object_id == tree.id and hit.distance == pytest.approx(-0.01, abs=2e-3)
    assert cc.check((*(centre + d * (r_tree + 0.31)), 1.0), IDENTITY) is None


def test_bad_collision_input():
    w = cufund.worlds.load("empty")
    with pytest.raises(ValueError, match="exactly one vehicle shape"):
        CollisionChecker(w)
    with pytest.raises(ValueError, match="box_size must be 3 finite numbers > 0"):
        CollisionChecker(w, box_size=(0.2, 0.0, 0.1))
    with pytest.raises(ValueError, match="radius must be a finite number > 0"):
        CollisionChecker(w, radius=-1.0)
    cc = CollisionChecker(w, radius=0.1)
    with pytest.raises(ValueError, match=r"p_W must have shape \(3,\)"):
        cc.check((0.0, 0.0), IDENTITY)
    with pytest.raises(ValueError, match="q_WB must be a finite non-zero quaternion"):
        cc.check((0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="margin must be a finite number >= 0"):
        cc.check((0.0, 0.0, 1.0), IDENTITY, margin=-0.1)
    raw = cufund._core.dynamics.CollisionWorld()
    with pytest.raises(ValueError, match=r"triangles must index vertices in \[0, 3\), got 5"):
        raw.add_mesh(np.zeros((3, 3)), [[0, 1, 5]])
