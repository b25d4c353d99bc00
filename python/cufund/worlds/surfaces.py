"""The floor under and the ceiling over a point of a world, for the ground and ceiling effect.

One ray straight down and one straight up through an Embree scene of the world's objects whose label names a large
surface (``floor``, ``ground``, ``ceiling``, ``terrain``, ``roof`` by default; the ground-effect models hold for a
plane under or over the rotors, not for a 5 cm bar); a miss is no surface (-inf / +inf), and with the dynamics'
ground plane the floor is at least z = 0 for a point above it. For the tunnel course the rays find its floor box
(top at z = 0) and ceiling box (bottom at the arena's height, 4 m).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cufund import _core

__all__ = ["SURFACE_LABELS", "SurfaceProbe", "apply_ground_effect"]

SURFACE_LABELS = ("floor", "ground", "ceiling", "terrain", "roof")

_MAX_RANGE = 1e4
_LIFT = 1e-3  # [m]
_SNAP = 1e-4  # [m]


class SurfaceProbe:
    """``probe(p_W) -> (floor_z, ceiling_z)`` [m] for points (n, 3) as an (n, 2) array."""

    def __init__(
        self, world: Any | None, ground_plane: bool = True, labels: tuple[str, ...] | None = SURFACE_LABELS
    ) -> None:
        objects = [] if world is None else [o for o in world.objects if labels is None or o.label in labels]
        self._meshes = [(o.vertices.astype(np.float32), o.triangles) for o in objects]
        self._ground_plane = ground_plane
        self._build()

    def _build(self) -> None:
        self._scene = None
        if self._meshes:
            self._scene = _core.lidar.RaycastScene()
            for vertices, triangles in self._meshes:
                self._scene.add_triangles(vertices, triangles)

    # Pickling (a plant keeps its probe): the meshes, the scene rebuilt from them (the C++ scene does not pickle).
    def __getstate__(self) -> dict[str, Any]:
        return {"meshes": self._meshes, "ground_plane": self._ground_plane}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self._meshes, self._ground_plane = state["meshes"], state["ground_plane"]
        self._build()

    def __call__(self, p_W: np.ndarray) -> np.ndarray:
        p = np.atleast_2d(np.asarray(p_W, dtype=float))
        n = p.shape[0]
        out = np.empty((n, 2))
        out[:, 0] = -math.inf
        out[:, 1] = math.inf
        if self._scene is not None:
            rays = np.zeros((2 * n, 6), dtype=np.float32)
            rays[:, :3] = np.repeat(p, 2, axis=0)
            rays[0::2, 5] = -1.0
            rays[1::2, 5] = 1.0
            rays[1::2, 2] += _LIFT  # the up ray starts above a floor the point lies on
            t = np.asarray(self._scene.cast_rays(rays)["t_hit"], dtype=float)
            t[1::2] += _LIFT
            hit = np.isfinite(t) & (t < _MAX_RANGE)
            down, up = t[0::2], t[1::2]
            out[hit[0::2], 0] = p[hit[0::2], 2] - down[hit[0::2]]
            out[hit[1::2], 1] = p[hit[1::2], 2] + up[hit[1::2]]
        if self._ground_plane:
            above = p[:, 2] >= 0.0
            out[above, 0] = np.maximum(out[above, 0], 0.0)
        out[:, 0] = np.minimum(out[:, 0], p[:, 2])  # a floor ray from inside an object: never above the point
        out[:, 1] = np.maximum(out[:, 1], out[:, 0])
        # The ray caster is float32: its hit heights carry ~1e-7 m of noise that changes with the vehicle's position.
        # Snapped to _SNAP, a flat floor or ceiling is one exact height (the noise carried no information and fed the
        # plant last-bit differences).
        finite = np.isfinite(out)
        out[finite] = np.round(out[finite] / _SNAP) * _SNAP
        return out


def apply_ground_effect(quad: Any, config: Any, world: Any | None) -> None:
    """Turns the ground and ceiling effect of ``config`` (a :class:`cufund.vehicle.ground_effect.GroundEffectConfig`,
    or None: off) on for ``quad``, the floor and ceiling looked up in ``world`` at ``config.update_hz`` (without a
    world: the ground plane, if any, and no ceiling, set once)."""
    if config is None:
        return
    quad.set_ground_effect(config)
    if world is not None and len(world) > 0:
        probe = SurfaceProbe(world, quad.params.ground_plane, config.surface_labels)
        quad.set_surface_probe(probe, 1.0 / config.update_hz)
