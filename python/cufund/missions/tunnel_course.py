"""Seeded tunnel courses: frames in a row with random openings, offsets and yaw, checked flyable.

Frame k's pose follows frame k-1's: ``spacing`` ahead along its heading, a lateral offset across it, a
vertical offset of the opening centre and a change of heading, each uniform within its bound. The first
frame (the entrance) stands at x = 0 within ``entrance_offset`` of y = 0 and ``entrance_yaw`` of +x.
Openings are drawn from ``openings`` (width x height): by default the IMAV scoring sizes 0.5, 1.0 and
1.5 m square and the paper's 0.5 x 1 m. A frame whose bottom bar is above the floor stands on two legs.

A layout is kept only if it is flyable for a vehicle of radius ``vehicle_radius``: the segment through
every opening is certified free on an ESDF of the course and the deterministic grid A* joins the
entry point to the first opening, each opening to the next, and the last to the exit point. Otherwise
the generator draws again (the same seed always gives the same course).
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cufund.worlds.world import World

__all__ = [
    "TunnelCourse",
    "TunnelCourseParams",
    "TunnelFrame",
    "paper_tunnel_course",
    "tunnel_course",
    "tunnel_course_layout",
]

_FRAME_COLOR = (0.9, 0.4, 0.1)


def _pair(name: str, v: Any, lo: float = 0.0) -> tuple[float, float]:
    a = tuple(float(x) for x in v)
    if len(a) != 2 or not all(math.isfinite(x) for x in a) or not lo <= a[0] <= a[1]:
        raise ValueError(f"{name} must be two finite numbers (min, max) with {lo} <= min <= max, got {v!r}")
    return a


def _bound(name: str, v: object) -> float:
    if isinstance(v, bool) or not isinstance(v, numbers.Real) or not (math.isfinite(v) and float(v) >= 0):
        raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
    return float(v)


@dataclass(frozen=True)
class TunnelCourseParams:
    """Bounds of a random tunnel course. Lengths [m], angles [deg]."""

    n_frames: int = 5
    """Frames in the course, >= 1."""
    openings: tuple[tuple[float, float], ...] = ((0.5, 0.5), (1.0, 1.0), (1.5, 1.5), (0.5, 1.0))
    """Opening sizes (width, height) [m] drawn uniformly per frame."""
    spacing: tuple[float, float] = (0.5, 1.5)
    """Distance from one frame to the next along the previous frame's heading (min, max) [m]."""
    lateral_offset: float = 0.3
    """Largest sideways offset of a frame from the previous one's axis [m]."""
    vertical_offset: float = 0.2
    """Largest change of the opening centre's height from frame to frame [m]."""
    yaw_change: float = 15.0
    """Largest change of heading from frame to frame [deg]."""
    entrance_offset: float = 1.0
    """The entrance frame is within this of y = 0 [m]."""
    entrance_yaw: float = 30.0
    """The entrance frame's heading is within this of +x [deg]."""
    first_height: tuple[float, float] = (0.6, 1.2)
    """Height of the entrance opening's centre above the floor (min, max) [m]."""
    bar: float = 0.05
    """Thickness and depth of the frames' bars [m]."""
    arena: tuple[float, float, float] = (12.0, 8.0, 4.0)
    """Inner size of the arena (x, y, z) [m]; it spans x from -arena_lead, y centred on 0, z from the floor."""
    arena_lead: float = 4.0
    """Length of arena before the entrance frame [m]."""
    vehicle_radius: float = 0.15
    """Radius [m] the flyability check requires the path to clear."""
    resolution: float = 0.025
    """Voxel edge [m] of the flyability check's distance field (its clearance bound is conservative by up to
    2 sqrt(3) x this: at 0.05 m most layouts with 0.5 m openings would be rejected for a 0.15 m radius)."""
    max_attempts: int = 100
    """Draws before giving up (ValueError)."""

    def __post_init__(self) -> None:
        if isinstance(self.n_frames, bool) or not isinstance(self.n_frames, numbers.Integral) or self.n_frames < 1:
            raise ValueError(f"n_frames must be an integer >= 1, got {self.n_frames!r}")
        ops = tuple(_pair("openings entry", o, lo=1e-3) if len(tuple(o)) == 2 else None for o in self.openings)
        if not ops or any(o is None for o in ops):
            raise ValueError(f"openings must be a non-empty list of (width, height) [m], got {self.openings!r}")
        object.__setattr__(self, "openings", ops)
        object.__setattr__(self, "spacing", _pair("spacing", self.spacing, lo=1e-3))
        object.__setattr__(self, "first_height", _pair("first_height", self.first_height, lo=0.0))
        for name in (
            "lateral_offset",
            "vertical_offset",
            "yaw_change",
            "entrance_offset",
            "entrance_yaw",
            "arena_lead",
            "vehicle_radius",
        ):
            object.__setattr__(self, name, _bound(name, getattr(self, name)))
        for name in ("bar", "resolution"):
            if _bound(name, getattr(self, name)) <= 0:
                raise ValueError(f"{name} must be > 0 [m], got {getattr(self, name)!r}")
        a = tuple(float(x) for x in self.arena)
        if len(a) != 3 or not all(math.isfinite(x) and float(x) > 0 for x in a):
            raise ValueError(f"arena must be 3 finite sizes > 0 [m], got {self.arena!r}")
        object.__setattr__(self, "arena", a)
        if (
            isinstance(self.max_attempts, bool)
            or not isinstance(self.max_attempts, numbers.Integral)
            or self.max_attempts < 1
        ):
            raise ValueError(f"max_attempts must be an integer >= 1, got {self.max_attempts!r}")
        for name, most in (("n_frames", 1000), ("max_attempts", 100_000), ("arena", 1e4)):
            value = max(getattr(self, name)) if name == "arena" else getattr(self, name)
            if value > most:
                raise ValueError(f"{name} must be at most {most:g}, got {getattr(self, name)!r}")


@dataclass(frozen=True)
class TunnelFrame:
    """One frame: its opening's centre, heading (the direction to fly through) and size."""

    centre_W: tuple[float, float, float]
    """Centre of the opening [m]."""
    yaw: float
    """Heading of the frame's axis from +x [rad]; the vehicle flies through along it."""
    width: float
    """Opening width [m] (across the axis, horizontal)."""
    height: float
    """Opening height [m]."""

    @property
    def axis_W(self) -> np.ndarray:
        return np.array([math.cos(self.yaw), math.sin(self.yaw), 0.0])

    def region(self, name: str, radius: float = 0.1) -> object:
        """A :class:`cufund.planning.Region` sphere of ``radius`` [m] at the opening's centre (for missions)."""
        from cufund.planning.mission_spec import Region

        return Region(name, self.centre_W, radius=radius)


@dataclass(frozen=True)
class TunnelCourse:
    """A generated course: the world, its frames in flying order, and the points before and after."""

    world: World
    frames: tuple[TunnelFrame, ...]
    entry_W: np.ndarray
    """A free point 1.5 m before the first opening, on its axis [m]."""
    exit_W: np.ndarray
    """A free point 1.5 m after the last opening [m]."""
    path_W: np.ndarray
    """The flyability check's path from entry to exit through every opening, (K, 3) [m]."""
    attempts: int = field(default=1)
    """Draws it took (1: the first was flyable)."""

    def regions(self, radius: float = 0.1) -> list:
        """The openings as mission regions ``gate1`` .. ``gateN`` (spheres at their centres), flying order."""
        return [f.region(f"gate{k + 1}", radius) for k, f in enumerate(self.frames)]


def _arena(world: World, p: TunnelCourseParams) -> None:
    """The built-in worlds' textured arena (floor, ceiling, four walls), starting arena_lead before x = 0."""
    from cufund.worlds.builtin import arena

    sx = p.arena[0]
    arena(world, p.arena, centre_xy=(sx / 2 - p.arena_lead, 0.0))


def _draw(rng: np.random.Generator, p: TunnelCourseParams) -> list[TunnelFrame]:
    frames = []
    yaw = math.radians(rng.uniform(-p.entrance_yaw, p.entrance_yaw))
    c = np.array([0.0, rng.uniform(-p.entrance_offset, p.entrance_offset), rng.uniform(*p.first_height)])
    for k in range(p.n_frames):
        w, h = p.openings[int(rng.integers(len(p.openings)))]
        if k > 0:
            ahead, side = rng.uniform(*p.spacing), rng.uniform(-p.lateral_offset, p.lateral_offset)
            axis, across = np.array([math.cos(yaw), math.sin(yaw)]), np.array([-math.sin(yaw), math.cos(yaw)])
            c = c.copy()
            c[:2] += ahead * axis + side * across
            c[2] += rng.uniform(-p.vertical_offset, p.vertical_offset)
            yaw += math.radians(rng.uniform(-p.yaw_change, p.yaw_change))
        c[2] = max(c[2], h / 2 + p.bar)  # the bottom bar on or above the floor
        frames.append(TunnelFrame((float(c[0]), float(c[1]), float(c[2])), float(yaw), float(w), float(h)))
    return frames


def _fits(frames: list[TunnelFrame], p: TunnelCourseParams, margin: float = 0.5) -> bool:
    sx, sy, sz = p.arena
    lo = np.array([-p.arena_lead + margin, -sy / 2 + margin, 0.0])
    hi = np.array([sx - p.arena_lead - margin, sy / 2 - margin, sz - margin])
    for f in frames:
        half = f.width / 2 + p.bar
        for s in (-1.0, 1.0):
            q = np.asarray(f.centre_W) + s * half * np.array([-math.sin(f.yaw), math.cos(f.yaw), 0.0])
            q[2] = f.centre_W[2] + f.height / 2 + p.bar
            if np.any(q < lo) or np.any(q > hi):
                return False
    return True


def _build(frames: list[TunnelFrame], p: TunnelCourseParams) -> World:
    world = World("tunnel_course")
    _arena(world, p)
    b = p.bar
    for f in frames:
        world.add_tunnel_frame(
            f.centre_W, width=f.width, height=f.height, depth=b, thickness=b, yaw=f.yaw, color=_FRAME_COLOR
        )
        gap = f.centre_W[2] - f.height / 2 - b  # from the floor to the frame's bottom
        if gap > 1e-9:
            across = np.array([-math.sin(f.yaw), math.cos(f.yaw), 0.0])
            for s in (-1.0, 1.0):
                leg = np.asarray(f.centre_W) + s * (f.width + b) / 2 * across
                leg[2] = gap / 2
                world.add_box((b, b, gap), tuple(leg), yaw=f.yaw, label="tunnel_frame", color=_FRAME_COLOR)
    return world


def _flyable(world: World, frames: list[TunnelFrame], p: TunnelCourseParams) -> np.ndarray | None:
    """The check's path (entry, through every opening, exit) or None."""
    from cufund.planning import GridPathSearch, GridPathSearchParams, clearance_from_world

    first, last = frames[0], frames[-1]
    entry = np.asarray(first.centre_W) - 1.5 * first.axis_W
    exit_ = np.asarray(last.centre_W) + 1.5 * last.axis_W
    pts = np.array([entry, exit_] + [f.centre_W for f in frames])
    sx, sy, sz = p.arena
    lo = np.maximum(pts.min(0) - 1.0, [-p.arena_lead, -sy / 2, 0.0])
    hi = np.minimum(pts.max(0) + [1.0, 1.0, 1.0], [sx - p.arena_lead, sy / 2, sz])
    lo[2], hi[2] = 0.0, min(sz, max(hi[2], max(f.centre_W[2] + f.height / 2 for f in frames) + 0.5))
    q = clearance_from_world(world, p.resolution, np.stack([lo - p.resolution, hi + p.resolution]), nthreads=1)
    r = p.vehicle_radius
    search = GridPathSearch(GridPathSearchParams(radius=r))
    path = [entry]
    for f in frames:
        d = 0.5 * p.bar + r + 2 * p.resolution  # just outside the bars' depth
        before = np.asarray(f.centre_W) - d * f.axis_W
        after = np.asarray(f.centre_W) + d * f.axis_W
        if not q.segment_free(before, after, r):
            return None
        leg = search.plan(q, path[-1], before)
        if not leg.found:
            return None
        path.extend(leg.path_W[1:])
        path.append(after)
    leg = search.plan(q, path[-1], exit_)
    if not leg.found:
        return None
    path.extend(leg.path_W[1:])
    return np.array(path)


def tunnel_course_layout(seed: int = 0, params: TunnelCourseParams | None = None) -> TunnelCourse:
    """A flyable course drawn from ``seed`` (see the module docstring); ValueError if none is found."""
    p = TunnelCourseParams() if params is None else params
    if not isinstance(p, TunnelCourseParams):
        raise TypeError(f"params must be a TunnelCourseParams, got {type(params).__name__}")
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    rng = np.random.default_rng(int(seed))
    for attempt in range(1, p.max_attempts + 1):
        frames = _draw(rng, p)
        if not _fits(frames, p):
            continue
        world = _build(frames, p)
        path = _flyable(world, frames, p)
        if path is not None:
            first, last = frames[0], frames[-1]
            return TunnelCourse(
                world=world,
                frames=tuple(frames),
                entry_W=np.asarray(first.centre_W) - 1.5 * first.axis_W,
                exit_W=np.asarray(last.centre_W) + 1.5 * last.axis_W,
                path_W=path,
                attempts=attempt,
            )
    raise ValueError(
        f"no flyable tunnel course for seed {seed} in {p.max_attempts} draws: widen the openings, "
        f"narrow the offsets or reduce vehicle_radius ({p.vehicle_radius} m)"
    )


def paper_tunnel_course(params: TunnelCourseParams | None = None) -> TunnelCourse:
    """The paper's IMAV 2025 layout (§3.2) in the generator's arena: five 0.5 m x 1 m openings standing on the
    floor, 0.5 m apart along +x from x = 0; checked flyable like a generated layout (ValueError if not, e.g. for
    a ``vehicle_radius`` the openings cannot pass)."""
    p = TunnelCourseParams() if params is None else params
    if not isinstance(p, TunnelCourseParams):
        raise TypeError(f"params must be a TunnelCourseParams, got {type(params).__name__}")
    frames = [TunnelFrame((0.5 * k, 0.0, 0.5 + p.bar), 0.0, 0.5, 1.0) for k in range(5)]
    world = _build(frames, p)
    path = _flyable(world, frames, p)
    if path is None:
        raise ValueError(f"the paper's tunnel layout is not flyable for vehicle_radius {p.vehicle_radius} m")
    return TunnelCourse(
        world=world,
        frames=tuple(frames),
        entry_W=np.asarray(frames[0].centre_W) - 1.5 * frames[0].axis_W,
        exit_W=np.asarray(frames[-1].centre_W) + 1.5 * frames[-1].axis_W,
        path_W=path,
    )


def tunnel_course(seed: int = 0, **kwargs: object) -> World:
    """The world of :func:`tunnel_course_layout`; keyword arguments are :class:`TunnelCourseParams` fields."""
    return tunnel_course_layout(seed, TunnelCourseParams(**kwargs)).world  # type: ignore[arg-type]
