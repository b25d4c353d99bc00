"""The search's finds: detections of people in the world frame associated into tracks, a track confirmed once two
of its detections were seen from views far enough apart and agree, and the metrics of the confirmed finds against
the people really placed (the metric alone reads those).

Association (gating by distance): a detection joins the track whose mean position is nearest, if within
``gate_m``; otherwise it starts a new track. Confirmation (two views and enough evidence): a track is confirmed
once it holds two detections whose camera positions are at least ``min_baseline_m`` apart and whose positions
agree within ``agree_m``, and at least ``min_strong`` detections scored ``confirm_score`` or more (by default every
detection is strong and one suffices); its position is then the mean of its detections' positions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

__all__ = ["SearchTrackParams", "SearchTracker", "Track", "search_metrics"]


@dataclass(frozen=True)
class SearchTrackParams:
    """How detections become confirmed finds. Lengths [m]."""

    gate_m: float = 2.0
    """A detection joins a track only if its position is within this of the track's mean [m]."""
    min_baseline_m: float = 3.0
    """Two views confirm only if the camera moved at least this far between them [m]."""
    agree_m: float = 1.5
    """Two views confirm only if their positions are within this of each other [m]."""
    min_score: float = 0.3
    """Detections scored below this are ignored [-]: they neither start nor join a track."""
    confirm_score: float | None = None
    """A detection scored at least this is a strong one [-] (at least ``min_score``); null: every detection
    kept is strong."""
    min_strong: int = 1
    """A track is confirmed only once it holds at least this many strong detections (and two views that agree
    from far enough apart, of any score): a second, higher threshold for confirming than for tracking, so a
    person seen weakly from many places is tracked across them while an object the detector scores high only
    now and then is not confirmed."""

    def __post_init__(self) -> None:
        for name in ("gate_m", "min_baseline_m", "agree_m"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be a finite number > 0 [m], got {v!r}")
        v = self.min_score
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 <= v <= 1.0:
            raise ValueError(f"min_score must be a number in [0, 1], got {v!r}")
        v = self.confirm_score
        if v is not None and (isinstance(v, bool) or not isinstance(v, (int, float)) or not self.min_score <= v <= 1):
            raise ValueError(f"confirm_score must be a number in [min_score, 1] or null, got {v!r}")
        v = self.min_strong
        if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= 1000:
            raise ValueError(f"min_strong must be an integer in [1, 1000] (detections), got {v!r}")


@dataclass
class Track:
    """One object seen (maybe several times): its detections' positions, camera positions and times."""

    positions: list[np.ndarray] = field(default_factory=list)
    cameras: list[np.ndarray] = field(default_factory=list)
    times: list[float] = field(default_factory=list)
    strong: int = 0
    """How many of its detections are strong (scored at least ``confirm_score``)."""
    two_views: bool = False
    """Whether two of its detections agree from views far enough apart."""
    confirmed_at: float | None = None
    """Time [s] of the detection that confirmed it (None: not confirmed)."""

    @property
    def mean(self) -> np.ndarray:
        return np.mean(self.positions, axis=0)


class SearchTracker:
    """Associates detections (world frame) into :class:`Track`s and confirms them from two views."""

    def __init__(self, params: SearchTrackParams | None = None) -> None:
        self.params = params or SearchTrackParams()
        self.tracks: list[Track] = []

    def add(self, t: float, p_W: np.ndarray, camera_W: np.ndarray, score: float = 1.0) -> Track:
        """Adds one detection at ``p_W`` seen at time ``t`` [s] from a camera at ``camera_W`` [m], scored
        ``score`` [-] (the caller drops those below ``min_score``); returns its track. Non-finite input is a
        ``ValueError`` naming it."""
        p = np.asarray(p_W, dtype=float).reshape(-1)
        c = np.asarray(camera_W, dtype=float).reshape(-1)
        for name, x in (("p_W", p), ("camera_W", c)):
            if x.shape != (3,) or not np.all(np.isfinite(x)):
                raise ValueError(f"{name} must be 3 finite numbers [m], got {x.tolist()}")
        best, best_d = None, self.params.gate_m
        for track in self.tracks:
            d = float(np.linalg.norm(track.mean - p))
            if d <= best_d:
                best, best_d = track, d
        if best is None:
            best = Track()
            self.tracks.append(best)
        if not best.two_views and self._confirms(best, p, c):
            best.two_views = True
        if self.params.confirm_score is None or float(score) >= self.params.confirm_score:
            best.strong += 1
        if best.confirmed_at is None and best.two_views and best.strong >= self.params.min_strong:
            best.confirmed_at = float(t)
        best.positions.append(p)
        best.cameras.append(c)
        best.times.append(float(t))
        return best

    def _confirms(self, track: Track, p: np.ndarray, c: np.ndarray) -> bool:
        """A new view (p, c) and one of the track's earlier views far apart and agreeing."""
        if not track.positions:
            return False
        far = np.linalg.norm(np.asarray(track.cameras) - c, axis=1) >= self.params.min_baseline_m
        agree = np.linalg.norm(np.asarray(track.positions) - p, axis=1) <= self.params.agree_m
        return bool(np.any(far & agree))

    def confirmed(self) -> list[Track]:
        """The confirmed tracks, in order of confirmation."""
        done = [k for k in self.tracks if k.confirmed_at is not None]
        return sorted(done, key=lambda k: float(k.confirmed_at))  # type: ignore[arg-type]

    def found(self) -> np.ndarray:
        """(n, 3) positions of the confirmed tracks [m] (confirmed tracks nearer than ``gate_m`` to an earlier
        one are merged into it: one person, two tracks)."""
        out: list[list[np.ndarray]] = []
        for track in self.confirmed():
            for group in out:
                if np.linalg.norm(np.mean(group, axis=0) - track.mean) <= self.params.gate_m:
                    group.extend(track.positions)
                    break
            else:
                out.append(list(track.positions))
        return np.array([np.mean(g, axis=0) for g in out], dtype=float).reshape(-1, 3)


def search_metrics(
    found_W: np.ndarray, people_W: np.ndarray, match_m: float = 2.0, t_found: float | None = None
) -> dict[str, object]:
    """Precision, recall and per-find position errors of ``found_W`` (n, 3) against the people really placed
    ``people_W`` (K, 3) [m]: finds and people are paired one to one minimising the summed distance (Hungarian),
    pairs farther than ``match_m`` apart do not count. ``search_precision`` = matched / n (1.0 with no finds:
    nothing was claimed wrongly), ``search_recall`` = matched / K (1.0 with no people),
    ``search_position_error_m`` the distance of each matched find [m] in the order of ``found_W``,
    ``search_time_s`` = ``t_found`` (when the last find was confirmed; None: no finds)."""
    f = np.asarray(found_W, dtype=float).reshape(-1, 3)
    p = np.asarray(people_W, dtype=float).reshape(-1, 3)
    if not (math.isfinite(match_m) and match_m > 0):
        raise ValueError(f"match_m must be a finite number > 0 [m], got {match_m!r}")
    errors: dict[int, float] = {}
    if len(f) and len(p):
        d = np.linalg.norm(f[:, None, :] - p[None, :, :], axis=2)
        rows, cols = linear_sum_assignment(np.where(d <= match_m, d, 1e6))
        errors = {int(r): float(d[r, c]) for r, c in zip(rows, cols, strict=True) if d[r, c] <= match_m}
    matched = len(errors)
    return {
        "search_precision": matched / len(f) if len(f) else 1.0,
        "search_recall": matched / len(p) if len(p) else 1.0,
        "search_position_error_m": [round(errors[i], 4) for i in sorted(errors)],
        "search_time_s": None if t_found is None else round(float(t_found), 3),
    }
