"""The foxglove.SceneUpdate messages of a log: the world's meshes and the detected tunnel frames, checked against
the World's own triangles and hand-computed corners."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cufund import messages as M
from cufund.logs.scene import tunnel_scene_update, world_scene_update
from cufund.worlds import World


def test_the_world_scene_holds_every_triangle_of_every_object_in_its_colour():
    world = World()
    world.add_box((1.0, 2.0, 3.0), (4.0, 0.0, 1.5), label="crate", color=(0.6, 0.4, 0.2))
    world.add_cylinder(0.2, 3.0, (0.0, 4.0, 1.5), label="tree")
    scene = json.loads(world_scene_update(world))
    assert [e["id"] for e in scene["entities"]] == ["world/0/crate", "world/1/tree"]
    for obj, entity in zip(world.objects, scene["entities"], strict=True):
        assert entity["frame_id"] == "world"
        (triangles,) = entity["triangles"]
        points = np.array([[p["x"], p["y"], p["z"]] for p in triangles["points"]])
        assert points.shape == (3 * len(obj.triangles), 3)
        assert np.allclose(points, obj.vertices[obj.triangles.reshape(-1)], atol=5e-5)  # rounded to 0.1 mm
        assert [triangles["color"][k] for k in "rgb"] == pytest.approx(obj.color)


def test_a_detected_frame_is_drawn_as_its_opening_and_its_normal():
    estimate = M.TunnelEstimate(
        2.0,
        np.array([[3.0, 1.0, 1.2]]),
        np.array([[0.0, 1.0, 0.0]]),  # facing +y: the opening spans x (width) and z (height)
        np.array([[0.8, 0.6]]),
        np.array([0.9]),
        12,
    )
    (entity,) = json.loads(tunnel_scene_update(estimate))["entities"]
    assert entity["timestamp"] == {"sec": 2, "nsec": 0} and entity["frame_id"] == "world"
    (line,) = entity["lines"]
    corners = np.array([[p["x"], p["y"], p["z"]] for p in line["points"]])
    assert np.allclose(corners[0], corners[-1])  # closed
    assert np.allclose(sorted(set(np.round(corners[:, 0], 9))), [2.6, 3.4])  # x = 3 -+ 0.4
    assert np.allclose(sorted(set(np.round(corners[:, 2], 9))), [0.9, 1.5])  # z = 1.2 -+ 0.3
    assert np.allclose(corners[:, 1], 1.0)
    (arrow,) = entity["arrows"]
    q = arrow["pose"]["orientation"]
    x, y, z, w = q["x"], q["y"], q["z"], q["w"]
    axis = np.array([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)])  # the arrow's +x
    assert np.allclose(axis, [0.0, 1.0, 0.0], atol=1e-12)


def test_a_tilted_frame_s_arrow_points_along_its_normal():
    normal = np.array([1.0, -1.0, 1.0]) / np.sqrt(3.0)
    estimate = M.TunnelEstimate(0.5, np.zeros((1, 3)), normal[None], np.array([[1.0, 1.0]]), np.array([0.5]), 3)
    (arrow,) = json.loads(tunnel_scene_update(estimate))["entities"][0]["arrows"]
    q = arrow["pose"]["orientation"]
    x, y, z, w = q["x"], q["y"], q["z"], q["w"]
    axis = np.array([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)])
    assert np.allclose(axis, normal, atol=1e-12)
