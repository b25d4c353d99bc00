"""The world's meshes and the detected tunnel frames as ``foxglove.SceneUpdate`` messages (JSON, JSON Schema).

JSON rather than Foxglove's protobuf: a scene is written once (the world) or at a few hertz (the detected
frames), so its size and cost do not matter, and JSON needs no protobuf descriptors in the package and reads with
any tool. The world is drawn from :class:`cufund.worlds.World`'s objects, the same triangle meshes the ray caster
and the replays use (one description of the world), each as a ``TriangleListPrimitive`` in ``world``.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from .cdr import stamp_sec_nsec

__all__ = ["SCENE_UPDATE", "tunnel_scene_update", "world_scene_update"]

SCENE_UPDATE = (
    "foxglove.SceneUpdate",
    json.dumps(
        {
            "title": "foxglove.SceneUpdate",
            "description": "An update to the entities displayed in a 3D scene (Foxglove schema, JSON encoding)",
            "type": "object",
            "properties": {"deletions": {"type": "array"}, "entities": {"type": "array"}},
        }
    ),
)
"""(schema name, JSON Schema) of a scene update."""

_IDENTITY = {"position": {"x": 0.0, "y": 0.0, "z": 0.0}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}


def _stamp(t: float) -> dict[str, int]:
    sec, nsec = stamp_sec_nsec(np.array([t]))
    return {"sec": max(int(sec[0]), 0), "nsec": int(nsec[0])}


def _entity(t: float, entity_id: str, **primitives: Any) -> dict[str, Any]:
    return {
        "timestamp": _stamp(t),
        "frame_id": "world",
        "id": entity_id,
        "lifetime": {"sec": 0, "nsec": 0},
        "frame_locked": False,
        "metadata": [],
        **primitives,
    }


_POINTS = "\x00points"


def _points_json(points: np.ndarray) -> str:
    """``[{"x": .., "y": .., "z": ..}, ...]`` of (N, 3) ``points`` to 0.1 mm, formatted in one C loop."""
    if not len(points):
        return "[]"
    return "[" + ",".join(['{"x":%.4f,"y":%.4f,"z":%.4f}'] * len(points)) % tuple(points.ravel().tolist()) + "]"


def world_scene_update(world: Any, t: float = 0.0) -> bytes:
    """One entity per object of ``world`` (a :class:`cufund.worlds.World`): its triangles in its colour."""
    entities, corner_lists = [], []
    for obj in world.objects:
        corner_lists.append(np.asarray(obj.vertices, dtype=np.float64)[np.asarray(obj.triangles).reshape(-1)])
        r, g, b = obj.color
        triangles = {
            "pose": _IDENTITY,
            "points": _POINTS,
            "color": {"r": r, "g": g, "b": b, "a": 0.5 if obj.label in ("floor", "ground") else 1.0},
            "colors": [],
            "indices": [],
        }
        entity = _entity(t, f"world/{obj.id}/{obj.label}", triangles=[triangles])
        entity["metadata"] = [{"key": "label", "value": obj.label}]
        entities.append(entity)
    parts = json.dumps({"deletions": [], "entities": entities}, separators=(",", ":")).split(json.dumps(_POINTS))
    out = [parts[0]]
    for corners, rest in zip(corner_lists, parts[1:], strict=True):  # the points spliced in, object by object
        out += [_points_json(corners), rest]
    return "".join(out).encode()


def tunnel_scene_update(estimate: Any) -> bytes:
    """The frames a tunnel detector found (a :class:`cufund.core.messages.TunnelEstimate`): each opening as a
    line strip in the estimated world frame, its normal as an arrow; replaces the previous detection."""
    lines, arrows = [], []
    for centre, normal, (width, height), confidence in zip(
        np.asarray(estimate.centres_W),
        np.asarray(estimate.normals_W),
        np.asarray(estimate.opening_sizes),
        np.asarray(estimate.confidence),
        strict=True,
    ):
        n = normal / max(float(np.linalg.norm(normal)), 1e-9)
        side = np.cross([0.0, 0.0, 1.0], n)
        side = side / max(float(np.linalg.norm(side)), 1e-9)
        up = np.cross(n, side)
        corners = [
            centre + sx * width / 2 * side + sz * height / 2 * up
            for sx, sz in ((1, 1), (-1, 1), (-1, -1), (1, -1), (1, 1))
        ]
        color = {"r": 1.0 - float(confidence), "g": float(confidence), "b": 0.2, "a": 1.0}
        lines.append(
            {
                "type": 0,
                "pose": _IDENTITY,
                "thickness": 0.03,
                "scale_invariant": False,
                "points": [{"x": float(x), "y": float(y), "z": float(z)} for x, y, z in corners],
                "color": color,
                "colors": [],
                "indices": [],
            }
        )
        yaw = float(np.arctan2(n[1], n[0]))
        pitch = float(-np.arcsin(np.clip(n[2], -1.0, 1.0)))
        cy, sy, cp, sp = np.cos(yaw / 2), np.sin(yaw / 2), np.cos(pitch / 2), np.sin(pitch / 2)
        arrows.append(
            {
                "pose": {
                    "position": {"x": float(centre[0]), "y": float(centre[1]), "z": float(centre[2])},
                    "orientation": {"x": -sy * sp, "y": cy * sp, "z": sy * cp, "w": cy * cp},
                },
                "shaft_length": 0.3,
                "shaft_diameter": 0.02,
                "head_length": 0.08,
                "head_diameter": 0.05,
                "color": color,
            }
        )
    entity = _entity(float(estimate.t), "detected_frames", lines=lines, arrows=arrows)
    return json.dumps({"deletions": [], "entities": [entity]}, separators=(",", ":")).encode()
