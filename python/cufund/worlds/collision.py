"""Collisions of the vehicle's shape with a world's meshes (Bullet, in cufund's C++ core).

A simulator ends a run as crashed when ``CollisionChecker.check`` returns a contact; that wiring
belongs to the simulator, this module only answers "does the vehicle at this pose touch anything".
"""

from __future__ import annotations

import dataclasses

import numpy as np

from cufund import _core

from .world import World


@dataclasses.dataclass(frozen=True)
class Contact:
    """The deepest contact between the vehicle and the world."""

    object_id: int
    """Id of the world object touched."""
    label: str
    """Its semantic label."""
    point_W: np.ndarray
    """(3,) contact point on the object's surface, world frame [m]."""
    normal_W: np.ndarray
    """(3,) unit normal from the object towards the vehicle."""
    distance: float
    """Signed distance [m]: negative = penetration depth, positive = gap (within the margin)."""


class CollisionChecker:
    """The vehicle as a box (``box_size`` = full edge lengths (x, y, z) [m] in the body frame, centred
    on the body origin) or a sphere (``radius`` [m]) against every mesh of ``world``.

    Objects whose label is in ``ignore_labels`` are left out (e.g. ``("floor", "ground")`` where the
    dynamics' own ground plane handles landing). Objects added to the world after construction are not
    seen; make a new checker.
    """

    def __init__(
        self,
        world: World,
        box_size: object | None = None,
        radius: float | None = None,
        ignore_labels: tuple[str, ...] = (),
    ) -> None:
        if (box_size is None) == (radius is None):
            raise ValueError("give exactly one vehicle shape: box_size (x, y, z) [m] or radius [m]")
        self._world = world
        self._labels = world.labels()
        self._cw = _core.dynamics.CollisionWorld()
        self._object_ids: list[int] = []  # world object id of each mesh given to Bullet
        for oid, obj in enumerate(world.objects):
            if obj.label in ignore_labels:
                continue
            self._cw.add_mesh(obj.vertices, obj.triangles)
            self._object_ids.append(oid)
        if box_size is not None:
            size = np.asarray(box_size, dtype=float)
            if size.shape != (3,) or not np.all(np.isfinite(size)) or np.any(size <= 0):
                raise ValueError(f"box_size must be 3 finite numbers > 0 (x, y, z) [m], got {box_size!r}")
            self._cw.set_vehicle_box(size / 2.0)
        else:
            self._cw.set_vehicle_sphere(float(radius))  # type: ignore[arg-type]

    def check(self, p_W: object, q_WB: object, margin: float = 0.0) -> Contact | None:
        """The deepest contact of the vehicle at pose (p_W [m], q_WB [w, x, y, z]) with signed distance
        <= ``margin`` [m], or None when it is clear of everything."""
        c = self._cw.check(p_W, q_WB, margin)
        if c is None:
            return None
        oid = self._object_ids[int(c["object_id"])]
        return Contact(
            oid, self._labels[oid], np.asarray(c["point_W"]), np.asarray(c["normal_W"]), float(c["distance"])
        )
