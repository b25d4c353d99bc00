"""Table 1 of the paper beside a tunnel run's figures: ``python -m cufund.missions.tunnel_table RUN/metrics.json``
(what ``make demo`` prints)."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

__all__ = ["PAPER_SIMULATION", "TARGETS", "table"]

PAPER_SIMULATION = {"odometry": (0.0217, 0.0962, 0.2577), "tracking": (0.0037, 0.0316, 0.0575)}
"""Table 1, simulation column (Gazebo + PX4 SITL): min, RMSE, max [m]."""
TARGETS = {"odometry": (None, 0.01, 0.03), "tracking": (None, 0.02, 0.04)}
"""Issue 14's targets: RMSE and max [m]."""


def _f(x: Any) -> str:
    return "-" if x is None else f"{x:.4f}"


def table(metrics: dict[str, Any]) -> str:
    """A Markdown table: the paper's simulation column, this run and the targets, for odometry and tracking error
    (min / RMSE / max [m]), then the run's status and other figures."""
    lines = ["| error (m) | paper, simulation | cufund | target |", "|---|---|---|---|"]
    for kind in ("odometry", "tracking"):
        for i, stat in enumerate(("min", "rmse", "max")):
            ours = metrics.get(f"{kind}_{stat}_m")
            target = TARGETS[kind][i]
            ok = "" if target is None or ours is None else (" ok" if ours <= target else " MISSED")
            lines.append(
                f"| {kind} {stat.upper() if stat == 'rmse' else stat} | {PAPER_SIMULATION[kind][i]:.4f} | "
                f"{_f(ours)} | {'-' if target is None else f'<= {target:g}'}{ok} |"
            )
    lines.append("")
    rtf, cpu_rtf = metrics.get("real_time_factor"), metrics.get("cpu_real_time_factor")
    lines.append(
        f"status: {metrics.get('status')}{' (' + metrics['reason'] + ')' if metrics.get('reason') else ''}, "
        f"success: {metrics.get('success')}, frames passed: {metrics.get('frames_passed')}, "
        f"mission time: {_f(metrics.get('mission_time_s'))} s, min clearance: "
        f"{_f(metrics.get('min_clearance_m'))} m, detection centre error (max): "
        f"{_f(metrics.get('detection_centre_error_m'))} m, real-time factor: "
        f"{'-' if rtf is None else f'{rtf:.2f}'}x wall, {'-' if cpu_rtf is None else f'{cpu_rtf:.2f}'}x "
        f"simulated seconds per CPU second"
    )
    split = metrics.get("time_per_component_s")
    if split:
        total = sum(split.values()) or 1.0
        lines.append("time per part: " + ", ".join(f"{k} {100 * v / total:.0f} %" for k, v in split.items() if v > 0))
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m cufund.missions.tunnel_table RUN_FOLDER/metrics.json", file=sys.stderr)
        return 2
    path = Path(args[0])
    if path.is_dir():
        path = path / "metrics.json"
    try:
        metrics = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        print(f"cannot read {path}: {e}", file=sys.stderr)
        return 2
    print(table(metrics))
    return 0 if metrics.get("success") else 1


if __name__ == "__main__":
    sys.exit(main())
