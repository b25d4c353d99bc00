"""Labelled objects for detection datasets: people (simple articulated meshes), cars, landing pads, gates and
tunnel frames. Each is one world object whose ``label`` is its class (:data:`CLASSES`), so the ray caster's
object id is its instance id and its label its class.

Every ``add_*`` places the object standing on the ground at ``position`` (x, y, z of its base) [m], turned by
``yaw`` [rad] about z, and returns its :class:`~cufund.worlds.world.WorldObject`.
"""

from __future__ import annotations

import numpy as np

from . import primitives
from .primitives import Mesh
from .world import World, WorldObject

CLASSES = ("tunnel_frame", "gate", "landing_pad", "person", "car")
"""The labels these objects carry, in class-index order of cufund's datasets."""


def _rot_y(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rot_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _limb(size: tuple[float, float, float], joint: tuple[float, float, float], swing: float) -> Mesh:
    """A box hanging down from ``joint`` (its top face's centre), swung by ``swing`` [rad] about y."""
    v, f = primitives.box(size)
    v = v - np.array([0.0, 0.0, size[2] / 2])  # top face at the origin
    return v @ _rot_y(swing).T + np.asarray(joint, float), f


def person_mesh(
    height: float = 1.75, arm_swing: tuple[float, float] = (0.0, 0.0), leg_swing: tuple[float, float] = (0.0, 0.0)
) -> Mesh:
    """A standing person ``height`` tall (feet at z = 0, facing +x): torso, head, two arms swung forward by
    ``arm_swing`` (left, right) [rad] at the shoulders and two legs by ``leg_swing`` at the hips."""
    h = primitives._positive("height", height)
    for name, pair in (("arm_swing", arm_swing), ("leg_swing", leg_swing)):
        a = np.asarray(pair, dtype=float)
        if a.shape != (2,) or not np.all(np.abs(a) <= np.pi / 2):
            raise ValueError(f"{name} must be 2 angles in [-π/2, π/2] [rad] (left, right), got {pair!r}")
    s = h / 1.75
    leg, torso, head_r = 0.85 * s, 0.6 * s, 0.11 * s
    hip_z, shoulder_z = leg, leg + torso
    parts: list[Mesh] = []
    v, f = primitives.box((0.22 * s, 0.38 * s, torso))
    parts.append((v + np.array([0.0, 0.0, hip_z + torso / 2]), f))
    v, f = primitives.sphere(head_r, 2)
    parts.append((v + np.array([0.0, 0.0, shoulder_z + 0.04 * s + head_r]), f))
    for side, sign in ((0, 1.0), (1, -1.0)):
        parts.append(
            _limb((0.09 * s, 0.09 * s, 0.7 * s), (0.0, sign * 0.245 * s, shoulder_z - 0.02 * s), -arm_swing[side])
        )
        parts.append(_limb((0.14 * s, 0.14 * s, leg), (0.0, sign * 0.1 * s, hip_z), -leg_swing[side]))
    v, f = primitives.merge(parts)
    v[:, 2] -= v[:, 2].min()  # a swung leg's corner is the lowest point: on the ground
    return v, f


def lying_person_mesh(height: float = 1.75) -> Mesh:
    """A person lying on its back along x (head at +x), at most 0.25 m high."""
    v, f = person_mesh(height)
    v = v @ _rot_y(np.pi / 2).T  # +z (head) -> +x... about y: z -> x
    v[:, 2] -= v[:, 2].min()
    return v, f


def car_mesh(length: float = 4.2, width: float = 1.8, height: float = 1.45) -> Mesh:
    """A car along x: body, cabin and four wheels (wheels on the ground)."""
    L, W, H = (primitives._positive(n, x) for n, x in (("length", length), ("width", width), ("height", height)))
    r = 0.3 * H / 1.45  # wheel radius: 0.3 m for a 1.45 m high car
    body_h = 0.55 * H - 0.15 * r
    parts: list[Mesh] = []
    v, f = primitives.box((L, W, body_h))
    parts.append((v + np.array([0.0, 0.0, r + body_h / 2 - 0.05]), f))
    cabin_h = H - (r + body_h - 0.05)
    v, f = primitives.box((0.5 * L, 0.9 * W, cabin_h))
    parts.append((v + np.array([-0.05 * L, 0.0, H - cabin_h / 2]), f))
    for x in (-0.32 * L, 0.32 * L):
        for y in (-W / 2 + 0.12, W / 2 - 0.12):
            v, f = primitives.cylinder(r, 0.22, 16)
            parts.append((v @ _rot_x(np.pi / 2).T + np.array([x, y, r]), f))
    return primitives.merge(parts)


def landing_pad_mesh(size: float = 1.2, thickness: float = 0.04) -> Mesh:
    """A square landing pad ``size`` wide with a raised 'H', lying on the ground."""
    a = primitives._positive("size", size)
    t = primitives._positive("thickness", thickness)
    parts: list[Mesh] = []
    v, f = primitives.box((a, a, t))
    parts.append((v + np.array([0.0, 0.0, t / 2]), f))
    bar, long = 0.1 * a, 0.6 * a
    for size3, centre in (
        ((long, bar, t / 2), (0.0, 0.2 * a, t * 1.25)),
        ((long, bar, t / 2), (0.0, -0.2 * a, t * 1.25)),
        ((bar, 0.4 * a, t / 2), (0.0, 0.0, t * 1.25)),
    ):
        v, f = primitives.box(size3)
        parts.append((v + np.array(centre), f))
    return primitives.merge(parts)


def gate_mesh(width: float = 1.5, height: float = 1.5, elevation: float = 1.0, thickness: float = 0.1) -> Mesh:
    """A racing gate: a square frame around a ``width`` × ``height`` opening whose centre is ``elevation`` above
    the frame's bottom bar plus posts down to the ground; flown through along x."""
    w, h = primitives._positive("width", width), primitives._positive("height", height)
    th = primitives._positive("thickness", thickness)
    e = primitives._positive("elevation", elevation)
    zc = e + h / 2 + th
    v, f = primitives.tunnel_frame(w, h, th, th)
    parts = [(v + np.array([0.0, 0.0, zc]), f)]
    post_h = zc - h / 2 - th
    for y in (-(w + th) / 2, (w + th) / 2):
        v, f = primitives.box((th, th, post_h))
        parts.append((v + np.array([0.0, y, post_h / 2]), f))
    return primitives.merge(parts)


def add_person(
    world: World,
    position: object,
    yaw: float = 0.0,
    height: float = 1.75,
    arm_swing: tuple[float, float] = (0.0, 0.0),
    leg_swing: tuple[float, float] = (0.0, 0.0),
    lying: bool = False,
    color: object = (0.8, 0.3, 0.3),
) -> WorldObject:
    mesh = lying_person_mesh(height) if lying else person_mesh(height, arm_swing, leg_swing)
    return world.add_mesh(*mesh, label="person", color=color, position=position, yaw=yaw)


def add_car(
    world: World, position: object, yaw: float = 0.0, color: object = (0.2, 0.3, 0.7), **size: float
) -> WorldObject:
    return world.add_mesh(*car_mesh(**size), label="car", color=color, position=position, yaw=yaw)


def add_landing_pad(
    world: World, position: object, yaw: float = 0.0, size: float = 1.2, color: object = (0.9, 0.9, 0.2)
) -> WorldObject:
    return world.add_mesh(*landing_pad_mesh(size), label="landing_pad", color=color, position=position, yaw=yaw)


def add_gate(
    world: World,
    position: object,
    yaw: float = 0.0,
    width: float = 1.5,
    height: float = 1.5,
    color: object = (0.1, 0.7, 0.3),
) -> WorldObject:
    return world.add_mesh(*gate_mesh(width, height), label="gate", color=color, position=position, yaw=yaw)


def add_tunnel_frame(
    world: World,
    position: object,
    yaw: float = 0.0,
    width: float = 0.5,
    height: float = 1.0,
    color: object = (0.9, 0.4, 0.1),
) -> WorldObject:
    """A tunnel frame (the course's) whose opening's centre is ``height`` / 2 + 0.05 m above ``position``."""
    p = np.asarray(position, dtype=float) + np.array([0.0, 0.0, height / 2 + 0.05])
    return world.add_tunnel_frame(p, width, height, yaw=yaw, color=color)


_SCATTER_KINDS = ("person", "car", "landing_pad", "gate")


def _random_mesh(kind: str, rng: np.random.Generator) -> Mesh:
    if kind == "person":
        if rng.random() < 0.1:
            return lying_person_mesh(float(rng.uniform(1.5, 1.9)))
        arms = rng.uniform(-0.8, 0.8, 2)
        legs = rng.uniform(-0.4, 0.4, 2)
        return person_mesh(float(rng.uniform(1.5, 1.9)), (arms[0], arms[1]), (legs[0], legs[1]))
    if kind == "car":
        return car_mesh()
    if kind == "landing_pad":
        return landing_pad_mesh()
    return gate_mesh()


def scatter(
    world: World,
    rng: np.random.Generator,
    n: int,
    kinds: tuple[str, ...] = _SCATTER_KINDS,
    region: tuple[tuple[float, float], tuple[float, float]] | None = None,
    clearance: float = 0.1,
) -> list[WorldObject]:
    """Adds ``n`` objects of ``kinds`` (drawn uniformly) on free ground (z = 0) in ``region`` ((x_min, x_max),
    (y_min, y_max)) [m], by default the world's horizontal bounds less 1 m. A spot is free when vertical rays up
    from the ground on a 0.1 m grid over the object's footprint (its rectangle grown by ``clearance`` [m]) meet
    nothing below the object's top (a tree, a wall, a ceiling, an object placed before) and do not start inside
    a closed mesh. People get random poses
    (one in ten lying), everything random colours and headings. Returns the objects added (fewer than ``n``
    when no free spot is found in 50 draws for one)."""
    if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n <= 10_000:
        raise ValueError(f"n must be an integer in [0, 10000], got {n!r}")
    unknown = [k for k in kinds if k not in _SCATTER_KINDS]
    if not kinds or unknown:
        raise ValueError(f"kinds must be among {', '.join(_SCATTER_KINDS)}, got {list(kinds)!r}")
    if region is None:
        lo, hi = world.bounds()
        region = ((lo[0] + 1.0, hi[0] - 1.0), (lo[1] + 1.0, hi[1] - 1.0))
    (x0, x1), (y0, y1) = region
    if not (x0 < x1 and y0 < y1):
        raise ValueError(f"region must be ((x_min, x_max), (y_min, y_max)) with min < max, got {region!r}")
    added: list[WorldObject] = []
    for _ in range(n):
        kind = kinds[int(rng.integers(len(kinds)))]
        v, f = _random_mesh(kind, rng)
        (ax, ay, _), (bx, by, top) = v.min(0) - clearance, v.max(0) + clearance
        gx, gy = np.meshgrid(
            np.linspace(ax, bx, max(int((bx - ax) / 0.1), 1) + 1), np.linspace(ay, by, max(int((by - ay) / 0.1), 1) + 1)
        )
        grid = np.stack([gx.ravel(), gy.ravel()], 1)
        for _ in range(50):
            x, y, yaw = rng.uniform(x0, x1), rng.uniform(y0, y1), float(rng.uniform(-np.pi, np.pi))
            c, s_ = np.cos(yaw), np.sin(yaw)
            rays = np.zeros((len(grid), 6), np.float32)
            rays[:, 0] = x + c * grid[:, 0] - s_ * grid[:, 1]
            rays[:, 1] = y + s_ * grid[:, 0] + c * grid[:, 1]
            rays[:, 2], rays[:, 5] = 0.02, 1.0
            if len(world):
                hit = world.raycast_scene.cast_rays(rays)
                # blocked: something below the top, or the spot is inside a closed mesh (a trunk, a wall: the ray
                # leaves it through a face whose outward normal points up, along the ray)
                if np.any(hit["t_hit"] < top) or np.any(np.isfinite(hit["t_hit"]) & (hit["normals"][:, 2] > 0)):
                    continue
            colour = tuple(float(k) for k in rng.random(3))
            added.append(world.add_mesh(v, f, label=kind, color=colour, position=(x, y, 0.0), yaw=yaw))
            break
    return added
