"""One drawing path for every world kind: each kind's world reaches the MeshCat scene whole, one mesh per label and
colour, with its own vertices (checked against the world the kind builds, decoded from the recorded commands)."""

from __future__ import annotations

import numpy as np
import pytest
import umsgpack

from cufund.scenarios import load_scenario
from cufund.scenarios.run_folder import world_of
from cufund.viz.meshcat_scene import import_meshcat
from cufund.viz.replay import _RecordingWindow
from cufund.viz.world_scene import draw_world, rgb_int

OBJ = """v 0 0 0
v 1 0 0
v 0 1 0
v 0 0 1
f 1 3 2
f 1 2 4
f 1 4 3
f 2 3 4
"""


def _world_yaml(tmp_path):
    (tmp_path / "tetra.obj").write_text(OBJ, encoding="utf-8")
    (tmp_path / "world.yaml").write_text(
        "name: mine\nobjects:\n"
        "  - {type: plane, size: [10, 10], position: [0, 0, 0], label: floor}\n"
        "  - {type: box, size: [1, 1, 2], position: [3, 0, 1], yaw: 0.3, label: crate, color: [0.6, 0.4, 0.2]}\n"
        "  - {type: mesh, path: tetra.obj, position: [1, 1, 0], scale: 2.0, label: statue}\n",
        encoding="utf-8",
    )
    return str(tmp_path / "world.yaml")


def _drawn(world) -> dict[str, tuple[np.ndarray, dict]]:
    window = _RecordingWindow()
    draw_world(import_meshcat().Visualizer(window=window), world)
    out = {}
    for c in (umsgpack.unpackb(b) for b in window.commands):
        assert c["type"] == "set_object" and c["path"].startswith("/meshcat/world/")
        geometry = c["object"]["geometries"][0]["data"]["attributes"]["position"]
        out[c["path"].rsplit("/", 1)[1]] = (
            np.frombuffer(geometry["array"].data, np.float32).reshape(-1, 3),
            c["object"]["materials"][0],
        )
    return out


@pytest.mark.parametrize(
    "world_spec",
    [
        "empty",
        "imav2025_tunnel",
        "corridor",
        {"kind": "forest", "n_trees": 30, "size": 20.0},
        {"kind": "tunnel_course", "seed": 3},
        "file",
    ],
    ids=["empty", "arena", "corridor", "forest", "tunnel_course", "file"],
)
def test_every_world_kind_is_drawn_whole(world_spec, tmp_path):
    if world_spec == "file":
        world_spec = {"kind": "file", "path": _world_yaml(tmp_path)}
    world = world_of(load_scenario("square", {"world": world_spec}))
    drawn = _drawn(world)
    labels = {o.label for o in world.objects} - {"ceiling"}
    assert labels <= set(drawn)  # each label's first colour under its own name
    for label in labels:
        objects = [o for o in world.objects if o.label == label]
        vertices = np.vstack([o.vertices for o in objects])
        got = np.vstack([v for name, (v, _) in drawn.items() if name == label or name.startswith(label + "_")])
        assert got.shape == vertices.shape and np.allclose(np.sort(got, axis=0), np.sort(vertices, axis=0), atol=1e-4)
        material = next(m for name, (_, m) in drawn.items() if name == label)
        assert material["color"] == rgb_int(objects[0].color)
        assert material["transparent"] == (label == "wall")
    # a ceiling would hide the flight from a camera above: never drawn
    assert "ceiling" not in drawn
