"""An LTLf mission typed in the page, turned into a visit order by the task planner and shown before it flies.

``{"command": "mission_preview", "formula": "F(a & F(b))", "regions": [{"name": "a", "centre_W": [x, y, z],
"radius": 0.3}, ...]}`` → the plan (regions in order, waypoints, length) computed by
:meth:`cufund.planning.MissionSpec.plan` from the vehicle's position; the gates the vehicle detected (``gate1``
..) are declared too. The page shows the waypoints as the planned path; ``mission_upload`` then flies them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cufund.core.config import ConfigError
from cufund.planning.mission_spec import MissionSpec, Region

__all__ = ["preview_mission"]


def _region(data: Any) -> Region:
    if not isinstance(data, dict):
        raise TypeError(f"each region must be an object with name, centre_W and radius or size, got {data!r}")
    unknown = set(data) - {"name", "centre_W", "radius", "size", "waypoint_W"}
    if unknown:
        raise ValueError(f"region fields are name, centre_W, radius, size, waypoint_W; got unknown {sorted(unknown)}")
    return Region(**data)


def preview_mission(command: dict[str, Any], world_regions: list[Region], start_W: Any) -> dict[str, Any]:
    """The plan of ``command`` (see the module docstring) as a JSON-able dict; a bad formula or region raises
    ``ValueError`` (``TypeError`` for a wrong type) naming it."""
    formula = command.get("formula")
    if not isinstance(formula, str) or not formula.strip():
        raise ValueError(f"mission_preview needs 'formula', a non-empty LTLf string, got {formula!r}")
    given = command.get("regions", [])
    if not isinstance(given, list):
        raise TypeError(f"'regions' must be a list of regions, got {type(given).__name__}")
    try:
        table = {r.name: r for r in world_regions}
        table.update({r.name: r for r in map(_region, given)})
        plan = MissionSpec.parse(formula).plan(table, np.asarray(start_W, dtype=float))
    except ConfigError as exc:
        raise ValueError(str(exc)) from exc
    return {
        "formula": formula,
        "regions": list(plan.regions),
        "waypoints_W": np.round(plan.waypoints_W, 4).tolist(),
        "length": round(float(plan.length), 4),
    }
