"""What ``cufund run`` prints when a run ends: a short human summary of its metrics (``--json`` prints them raw).

Numbers are shown to 3 significant digits with their units (lengths under a metre in millimetres); the tunnel
mission's runs print the paper's Table 1 beside the run (:func:`cufund.missions.tunnel_table.table`). Everything
else is in the run folder's ``metrics.json``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

__all__ = ["significant", "summary"]


def significant(x: float, digits: int = 3) -> str:
    """``x`` rounded to ``digits`` significant digits, written without an exponent from 1e-3 to 1e6
    (``0.0322``, ``30.8``, ``1230``), with one outside (``1.23e+07``)."""
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        return str(x)
    if not math.isfinite(x) or x == 0:
        return f"{x:g}"
    e = math.floor(math.log10(abs(x)))
    r = round(x, digits - 1 - e)
    if r != 0:
        e = math.floor(math.log10(abs(r)))  # 9.996 rounds to 10.0: one digit fewer after the point
    if not -3 <= e < 6:
        return f"{x:.{digits - 1}e}"
    return f"{round(x, digits - 1 - e):.{max(digits - 1 - e, 0)}f}"


def _length(x: Any) -> str:
    if not isinstance(x, (int, float)) or isinstance(x, bool):
        return "-"
    return f"{significant(1000 * x)} mm" if abs(x) < 1 else f"{significant(x)} m"


def _joined(metrics: dict[str, Any], fields: list[tuple[str, str, str]]) -> str:
    """``label value`` for each (label, key, unit) whose key the metrics hold; unit 'm' shows a length."""
    parts = []
    for label, key, unit in fields:
        v = metrics.get(key)
        if v is None or isinstance(v, (dict, list)):
            continue
        if isinstance(v, bool):
            text = "yes" if v else "no"
        elif unit == "m":
            text = _length(v)
        elif isinstance(v, (int, float)):
            text = f"{significant(v) if isinstance(v, float) else v}{' ' + unit if unit else ''}"
        else:
            text = str(v)
        parts.append(f"{label} {text}" if label else text)
    return ", ".join(parts)


_LINES: list[tuple[str, list[tuple[str, str, str]]]] = [
    ("tracking error", [("RMSE", "tracking_rmse_m", "m"), ("max", "tracking_max_m", "m")]),
    (
        "odometry error",
        [
            ("RMSE", "odometry_rmse_m", "m"),
            ("max", "odometry_max_m", "m"),
            ("aligned ATE", "odometry_ate_aligned_m", "m"),
        ],
    ),
    ("attitude error", [("RMSE", "odometry_rot_rmse_deg", "deg")]),
    (
        "LiDAR odometry",
        [("", "lio_scans", "scans"), ("median", "lio_ms_per_scan_median", "ms per scan")],
    ),
    (
        "VIO",
        [("", "vio_frames", "frames"), ("median", "vio_ms_per_frame_median", "ms per frame")],
    ),
    (
        "mission",
        [
            ("success", "success", ""),
            ("time", "mission_time_s", "s"),
            ("goal reached at", "goal_reached_s", "s"),
            ("frames passed", "frames_passed", ""),
            ("items reached", "mission_items_reached", ""),
            ("path", "path_length_m", "m"),
            ("min clearance", "min_clearance_m", "m"),
            ("replans", "replans", ""),
        ],
    ),
]


def summary(metrics: dict[str, Any], folder: Path, mission_kind: str | None = None) -> str:
    """The lines ``cufund run`` prints for a run with ``metrics`` written to ``folder``: the status, the key
    figures with units at 3 significant digits (the tunnel mission: its Table 1), the run folder."""
    status = metrics.get("status", "?")
    message = metrics.get("message") or ""
    lines: list[str] = []
    if mission_kind == "tunnel":
        from cufund.missions.tunnel_table import table

        lines += [table(metrics), ""]
    else:
        sim, wall = metrics.get("sim_time_s"), metrics.get("wall_time_s")
        if isinstance(sim, (int, float)) and isinstance(wall, (int, float)):
            rtf = metrics.get("real_time_factor")
            speed = f" ({significant(rtf)}x real time)" if isinstance(rtf, (int, float)) else ""
            lines.append(f"  {'simulated':<16}{significant(sim)} s in {significant(wall)} s of wall time{speed}")
        for label, fields in _LINES:
            text = _joined(metrics, fields)
            if text:
                lines.append(f"  {label:<16}{text}")
        realism = metrics.get("realism")
        if isinstance(realism, dict) and realism.get("profile"):
            lines.append(f"  {'realism':<16}{realism['profile']}")
    lines.append(f"status: {status}{f' ({message})' if message else ''}")
    lines.append(f"run folder: {folder.resolve()}")
    lines.append(f"every metric: {(folder / 'metrics.json').resolve()} (or cufund run ... --json)")
    return "\n".join(lines)
