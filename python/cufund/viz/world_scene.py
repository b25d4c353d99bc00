"""A scenario's world in a MeshCat scene, for every world kind (forest, arena, tunnel course, corridor, a world
file's meshes): drawn from the world's own objects (:class:`cufund.worlds.World`: the triangle meshes, labels and
colours the simulated sensors see), the one description every world kind produces."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .meshcat_scene import import_meshcat

__all__ = ["HIDDEN_LABELS", "TRANSLUCENT_LABELS", "WORLD", "WorldLayer", "draw_world", "rgb_int", "world_layers"]

WORLD = "world"
"""The MeshCat path the world is drawn under."""
HIDDEN_LABELS = ("ceiling",)
"""Objects not drawn: a ceiling would hide the flight from any camera above it."""
TRANSLUCENT_LABELS = ("wall",)
"""Objects drawn see-through, so that a camera outside an arena sees into it."""


@dataclass(frozen=True)
class WorldLayer:
    """The world's objects of one label and colour, merged into one mesh (620 trees: one draw call)."""

    label: str
    color: tuple[float, float, float]
    vertices: np.ndarray
    """(V, 3) world frame [m]."""
    triangles: np.ndarray
    """(T, 3) vertex indices."""
    count: int
    """Objects merged."""

    @property
    def opacity(self) -> float:
        return 0.25 if self.label in TRANSLUCENT_LABELS else 1.0


def rgb_int(color: tuple[float, float, float]) -> int:
    """0xRRGGBB from RGB in [0, 1]."""
    r, g, b = (int(round(255 * float(np.clip(c, 0.0, 1.0)))) for c in color)
    return r << 16 | g << 8 | b


def world_layers(world: Any) -> list[WorldLayer]:
    """The world's objects grouped by (label, colour), in the order of their first object; hidden labels left out."""
    groups: dict[tuple[str, tuple[float, float, float]], list[Any]] = {}
    for obj in world.objects:
        if obj.label in HIDDEN_LABELS:
            continue
        groups.setdefault((obj.label, tuple(obj.color)), []).append(obj)
    layers = []
    for (label, color), objs in groups.items():
        offsets = np.cumsum([0] + [len(o.vertices) for o in objs[:-1]])
        vertices = np.vstack([np.asarray(o.vertices, dtype=float) for o in objs])
        triangles = np.vstack([np.asarray(o.triangles) + off for o, off in zip(objs, offsets, strict=True)])
        layers.append(WorldLayer(label, color, vertices, triangles.astype(np.int64), len(objs)))
    return layers


def draw_world(vis: Any, world: Any) -> list[tuple[str, int]]:
    """Draws ``world`` under ``world/<label>`` (one mesh per label and colour); returns the legend entries
    (label, 0xRRGGBB), one per layer."""
    g = import_meshcat().geometry
    legend: list[tuple[str, int]] = []
    names: dict[str, int] = {}
    for layer in world_layers(world):
        k = names[layer.label] = names.get(layer.label, -1) + 1
        name = layer.label if k == 0 else f"{layer.label}_{k}"
        color = rgb_int(layer.color)
        vis[WORLD][name].set_object(
            g.TriangularMeshGeometry(layer.vertices, layer.triangles),
            g.MeshLambertMaterial(color=color, opacity=layer.opacity, transparent=layer.opacity < 1.0),
        )
        legend.append((layer.label if layer.count == 1 else f"{layer.label} ({layer.count})", color))
    return legend
