"""The fleet-wide figure of a fleet run folder, ``fleet`` (PNG and SVG): every vehicle's true trajectory in one top
view and the separation of every pair over time, the closest approach marked (docs/guides/fleets.md).

Vehicle ``i`` is drawn in matplotlib's ``tab10`` colour ``i % 10``, the palette the fleet ground station uses.
Separation is the centre-to-centre distance of the true positions, from each vehicle's recorded states on the union
of their instants (a vehicle whose run has ended stays where it ended), so its minimum may differ from the fleet's
``fleet_min_separation_m`` (checked at the interaction rate) by what moves between two records.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from itertools import combinations
from pathlib import Path
from typing import Any

import numpy as np

from .plots import pyplot, save_figure

__all__ = ["fleet_separation", "plot_fleet", "write_fleet_figure"]


def _colour(i: int) -> Any:
    return pyplot().get_cmap("tab10")(i % 10)


def fleet_separation(
    tracks: Mapping[str, tuple[np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, dict[tuple[str, str], np.ndarray]]:
    """The union of the tracks' instants (K,) [s] and each pair's centre-to-centre distance there (K,) [m], from
    ``tracks`` ``{name: (t (N,), p_W (N, 3))}`` (each held at its first and last position outside its span)."""
    names = list(tracks)
    if len(names) < 2:
        return np.zeros(0), {}
    t = np.unique(np.concatenate([np.asarray(tr[0], dtype=float) for tr in tracks.values()]))
    p = {}
    for n, (tn, pn) in tracks.items():
        tn, pn = np.asarray(tn, dtype=float), np.asarray(pn, dtype=float).reshape(-1, 3)
        p[n] = np.stack([np.interp(t, tn, pn[:, k]) for k in range(3)], 1)
    return t, {(a, b): np.linalg.norm(p[a] - p[b], axis=1) for a, b in combinations(names, 2)}


def plot_fleet(
    tracks: Mapping[str, tuple[np.ndarray, np.ndarray]],
    stem: str | Path,
    title: str = "",
    collisions: Sequence[Mapping[str, Any]] = (),
    min_separation_m: float | None = None,
) -> list[Path]:
    """Writes ``stem``.png and .svg: the top view of ``tracks`` ``{name: (t (N,) [s], p_W (N, 3) [m])}`` (start: a
    circle, end: a square, each in the vehicle's colour; ``collisions``: the fleet's ``fleet_collision_events``,
    red crosses) and each pair's separation over time with the closest approach marked; ``min_separation_m``: a
    required separation drawn as a dashed line. Returns the paths."""
    plt = pyplot()
    names = list(tracks)
    fig, (top, sep) = plt.subplots(
        1, 2, figsize=(13.0, 5.6), gridspec_kw={"width_ratios": [1.0, 1.25]}, layout="constrained"
    )
    for i, n in enumerate(names):
        p = np.asarray(tracks[n][1], dtype=float).reshape(-1, 3)
        if len(p) == 0:
            continue
        c = _colour(i)
        top.plot(p[:, 0], p[:, 1], color=c, lw=1.6, label=n, zorder=2)
        top.plot(*p[0, :2], "o", ms=7, mfc=c, mec="white", mew=1.0, zorder=4)
        top.plot(*p[-1, :2], "s", ms=12, mfc="none", mec=c, mew=2.0, zorder=5)  # hollow: a start under it shows
    for k, ev in enumerate(collisions):
        x, y = ev["point_W"][:2]
        top.plot(x, y, "x", color="#d62728", ms=12, mew=3, zorder=5, label="collision" if k == 0 else None)
    # legend entries for the markers, in neutral grey
    top.plot([], [], "o", ms=7, mfc="0.45", mec="white", label="start")
    top.plot([], [], "s", ms=10, mfc="none", mec="0.45", mew=2.0, label="end")
    t, pairs = fleet_separation(tracks)
    closest = None
    if pairs:
        stacked = np.stack(list(pairs.values()))
        d, which = stacked.min(axis=0), stacked.argmin(axis=0)
        k = int(np.argmin(d))
        a, b = list(pairs)[int(which[k])]
        closest = (k, a, b)
        at = [[np.interp(t[k], tracks[n][0], np.asarray(tracks[n][1])[:, j]) for j in (0, 1)] for n in (a, b)]
        top.plot(*np.transpose(at), "--", color="#d62728", lw=1.5, zorder=6, label="closest approach")
    top.set_aspect("equal", adjustable="datalim")
    top.set_xlabel("x (east) [m]")
    top.set_ylabel("y (north) [m]")
    top.set_title("Top view (truth)")
    top.grid(True, color="0.9", zorder=0)
    top.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=min(6, len(names) + 3), fontsize=9, frameon=False)

    if closest is not None:
        k, a, b = closest
        for u, w in pairs:
            mix = tuple((np.asarray(_colour(names.index(u))) + np.asarray(_colour(names.index(w)))) / 2)
            sep.plot(t, pairs[(u, w)], color=mix, lw=1.1, alpha=0.85, label=f"{u}–{w}")
        sep.plot(t, d, color="black", lw=2.0, label="closest pair", zorder=3)
        sep.plot(t[k], d[k], "o", ms=9, color="#d62728", zorder=5)
        sep.annotate(
            f"min {d[k]:.2f} m\n{a}–{b}, t = {t[k]:.1f} s",
            (t[k], d[k]),
            xytext=(0.5, 0.95),
            textcoords="axes fraction",
            ha="center",
            va="top",
            fontsize=10,
            bbox={"boxstyle": "round", "fc": "white", "ec": "#d62728"},
            arrowprops={"arrowstyle": "->", "color": "#d62728"},
        )
        if min_separation_m is not None:
            sep.axhline(min_separation_m, color="#d62728", ls="--", lw=1.0, label="required")
        sep.set_ylim(0.0, max(float(stacked.max()) * 1.4, 1.0))  # room for the note above the curves
        sep.set_xlim(float(t[0]), float(t[-1]))
        sep.legend(
            loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=min(5, len(pairs) + 2), fontsize=9, frameon=False
        )
    else:
        sep.text(0.5, 0.5, "one vehicle: no separation", ha="center", va="center", transform=sep.transAxes)
    sep.set_xlabel("time [s]")
    sep.set_ylabel("separation (centre to centre) [m]")
    sep.set_title("Separation of each pair")
    sep.grid(True, color="0.9")
    if title:
        fig.suptitle(title, fontsize=12)
    return save_figure(fig, stem)


def write_fleet_figure(run: Any, out: str | Path) -> list[Path]:
    """``fleet.png`` / ``fleet.svg`` in the fleet's run folder ``out`` from its finished
    :class:`~cufund.scenarios.fleet.FleetRun` (each vehicle's recorded truth; the fleet mission's
    ``min_separation`` as the required separation when it has one)."""
    tracks = {n: (r.result.states["t"], r.result.states["p_W"]) for n, r in run.runs.items()}
    m = run.metrics
    mission = getattr(run.config, "mission", None)
    required = None
    if mission is not None and getattr(mission, "kind", "") == "fleet":
        required = getattr(mission.params, "min_separation", None)
    sep = m.get("fleet_min_separation_m")
    title = (
        f"{run.config.name}: {len(tracks)} vehicles, {run.status}, closest approach "
        f"{'-' if sep is None else f'{sep:.2f} m'}, collisions {m.get('fleet_collisions', 0)}"
    )
    return plot_fleet(tracks, Path(out) / "fleet", title, m.get("fleet_collision_events", ()), required)
