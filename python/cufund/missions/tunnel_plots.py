"""What the tunnel run adds to its run folder: the gates (true and detected), the course's centre line and the
mission's phases for the run's figures and replay (:class:`cufund.viz.flight.Flight`, drawn by
:mod:`cufund.viz.plots` and :mod:`cufund.viz.replay` as for every run), the detected centres and the detector's
map in the replay, and ``detection`` (PNG and SVG: the detector's Fig.-9-style plot)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .tunnel_metrics import true_frames

__all__ = ["add_tunnel_flight", "mission_phases", "write_tunnel_outputs"]

_ORANGE, _MAP = 0xFF7F0E, 0x9467BD


def mission_phases(transitions: list[tuple[float, str, str]], t_end: float) -> list[Any]:
    """The mission's states as contiguous phases (a state entered again right after itself is one phase)."""
    from cufund.viz.flight import Phase

    phases: list[Phase] = []
    for k, (t, state, _) in enumerate(transitions):
        t1 = transitions[k + 1][0] if k + 1 < len(transitions) else t_end
        if phases and phases[-1].name == state:
            phases[-1] = Phase(phases[-1].t0, t1, state)
        elif t1 > t:
            phases.append(Phase(float(t), float(min(t1, t_end)), state))
    return phases


def add_tunnel_flight(flight: Any, mission: Any, course: Any, detector: Any) -> None:
    """Adds to ``flight`` the true gates and the course's centre line (the flyability path through the true
    openings), the gates the flown plan went through, the mission's phases, and the detected centres and the
    detector's map as replay overlays."""
    from cufund.viz.flight import Gate, Overlay

    if course is not None:
        c, n, s, _ = true_frames(course)
        flight.gates += [Gate(c[k], n[k], float(s[k, 0]), float(s[k, 1])) for k in range(len(c))]
        flight.centreline_W = np.asarray(course.path_W, dtype=float)
    d = mission.used
    if d is not None:
        flight.gates += [
            Gate(np.asarray(cc), np.asarray(nn), float(ss[0]), float(ss[1]), detected=True)
            for cc, nn, ss in zip(d.centres, d.normals, d.sizes, strict=True)
        ]
        flight.overlays.append(
            Overlay("detected_centres", np.asarray(d.centres), _ORANGE, "markers", "detected centres")
        )
    cloud = _cloud(detector)
    if len(cloud):
        flight.overlays.append(Overlay("detector_map", cloud, _MAP, "cloud", "detector's map"))
    flight.phases = mission_phases(list(mission.transitions), float(flight.t[-1]))
    flight.phases_title = "mission states"


def _cloud(detector: Any) -> np.ndarray:
    """The detector's accumulated map (voxel means, world frame) [m]."""
    try:
        return np.asarray(detector.map_points_W(), dtype=float).reshape(-1, 3)
    except (AttributeError, ZeroDivisionError, ValueError):
        return np.zeros((0, 3))


def write_tunnel_outputs(
    run: Any,
    out: str | Path,
    mission: Any,
    course: Any,
    detector: Any,
    plots: bool = True,
    replay: bool = True,
    flight: Any = None,
) -> None:
    """The tunnel's output hook: adds the tunnel's layers to ``flight`` (the run folder then draws it) and writes
    ``detection.png``/``.svg`` into ``out``."""
    if flight is not None:
        add_tunnel_flight(flight, mission, course, detector)
    if plots:
        _detection_plot(Path(out) / "detection", detector, course)


def _detection_plot(stem: Path, detector: Any, course: Any) -> None:
    """The detector's Fig.-9-style plot of its map and tracked frames, with the true centres."""
    from cufund.perception.plot import plot_detection
    from cufund.viz.plots import pyplot, save_figure

    cloud = _cloud(detector)
    if cloud.shape[0] == 0:
        return
    pyplot()  # on the Agg backend
    truth = None if course is None else np.array([f.centre_W for f in course.frames])
    save_figure(plot_detection(cloud, detector.frames(), truth), stem)
