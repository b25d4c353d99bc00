"""``vio_room``: an indoor room for visual(-inertial) odometry, like EuRoC's Vicon room.

An 8 m (x) × 6 m (y) × 3 m (z) room centred on the origin, floor at z = 0, open to the sky (the sun lights it and
its walls cast shadows), with textured walls (brick and concrete), a concrete floor with rugs, posters on every wall, shelves along the walls and crates in the corners; a
seeded layout of posters, rugs and crates. The middle 5 m × 3 m of the floor is left free for flying.
"""

from __future__ import annotations

import numpy as np

from .materials import Material
from .world import World

SIZE = (8.0, 6.0, 3.0)
"""Inner size of the room (x, y, z) [m]."""


def _colour(rng: np.random.Generator, lo: float, hi: float) -> tuple[float, float, float]:
    r, g, b = rng.uniform(lo, hi, 3)
    return (float(r), float(g), float(b))


def vio_room(seed: int = 0) -> World:
    """The room (see the module's docstring), its posters, rugs and crates placed from ``seed``."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    rng = np.random.default_rng(seed)
    world = World("vio_room")
    sx, sy, sz = SIZE
    t = 0.1  # wall thickness
    concrete = Material((0.72, 0.71, 0.68), "concrete", scale=0.08, contrast=0.5, seed=seed + 1)
    floor = Material((0.55, 0.52, 0.48), "concrete", scale=0.05, contrast=0.6, seed=seed + 2)
    brick = Material((0.70, 0.36, 0.26), "brick", scale=0.25, albedo2=(0.80, 0.78, 0.74), seed=seed + 3)
    world.add_box((sx + 2 * t, sy + 2 * t, t), (0.0, 0.0, -t / 2), label="floor", color=(0.5, 0.5, 0.5), material=floor)
    walls = [  # (size, centre, inward normal, material)
        ((t, sy, sz), (-(sx + t) / 2, 0.0, sz / 2), (1.0, 0.0), brick),
        ((t, sy, sz), ((sx + t) / 2, 0.0, sz / 2), (-1.0, 0.0), concrete),
        ((sx, t, sz), (0.0, -(sy + t) / 2, sz / 2), (0.0, 1.0), concrete),
        ((sx, t, sz), (0.0, (sy + t) / 2, sz / 2), (0.0, -1.0), brick),
    ]
    for size, centre, _, mat in walls:
        world.add_box(size, centre, label="wall", material=mat)
    # posters: thin boxes 2 cm off each wall, high-contrast noise at a few cm scale
    for _size, centre, normal, _ in walls:
        along_x = normal[0] == 0.0
        span = sx if along_x else sy
        n = 3 if along_x else 2
        slots = (np.arange(n) + 0.5) / n * span - span / 2
        for s in slots:
            w, h = rng.uniform(0.6, 1.1), rng.uniform(0.6, 1.0)
            z = rng.uniform(1.0, 2.2)
            off = s + rng.uniform(-0.3, 0.3)
            pos = (
                (off, centre[1] + normal[1] * (t / 2 + 0.01), z)
                if along_x
                else (centre[0] + normal[0] * (t / 2 + 0.01), off, z)
            )
            size = (w, 0.02, h) if along_x else (0.02, w, h)
            colour = _colour(rng, 0.5, 1.0)
            mat = Material(
                colour, "noise", scale=rng.uniform(0.02, 0.05), contrast=0.9, seed=int(rng.integers(1 << 30))
            )
            world.add_box(size, pos, label="poster", material=mat)
    # shelves along the -x and +y walls
    wood = Material((0.55, 0.40, 0.25), "bark", scale=0.3, contrast=0.5, seed=seed + 4)
    for pos, size in (
        ((-sx / 2 + 0.25, -1.8, 0.9), (0.4, 1.2, 1.8)),
        ((-sx / 2 + 0.25, 1.8, 0.9), (0.4, 1.2, 1.8)),
        ((2.5, sy / 2 - 0.25, 0.9), (1.4, 0.4, 1.8)),
    ):
        world.add_box(size, pos, label="shelf", material=wood)
        for k in range(3):  # books: rows of small coloured boxes on each shelf level
            z = pos[2] - size[2] / 2 + 0.35 + 0.55 * k
            colour = _colour(rng, 0.2, 0.9)
            mat = Material(colour, "noise", scale=0.02, contrast=0.8, seed=int(rng.integers(1 << 30)))
            bsize = (0.1, size[1] * 0.9, 0.25) if size[0] < size[1] else (size[0] * 0.9, 0.1, 0.25)
            off = (
                np.array([size[0] / 2 + 0.05, 0.0, 0.0])
                if size[0] < size[1]
                else np.array([0.0, -size[1] / 2 - 0.05, 0.0])
            )
            world.add_box(bsize, (pos[0] + off[0], pos[1] + off[1], z), label="books", material=mat)
    # crates in the corners, rugs on the floor
    for cx, cy in ((3.4, -2.4), (3.3, 2.2), (-1.5, -2.5)):
        e = rng.uniform(0.4, 0.7)
        mat = Material(_colour(rng, 0.4, 0.9), "checker", scale=e / 4, contrast=0.7)
        world.add_box((e, e, e), (cx, cy, e / 2), yaw=float(rng.uniform(0, np.pi / 2)), label="crate", material=mat)
    for _ in range(3):
        w, h = rng.uniform(1.0, 2.0), rng.uniform(0.8, 1.5)
        x, y = rng.uniform(-2.5, 2.5), rng.uniform(-1.5, 1.5)
        colour = _colour(rng, 0.3, 0.9)
        mat = Material(colour, "noise", scale=0.04, contrast=0.85, seed=int(rng.integers(1 << 30)))
        world.add_box((w, h, 0.01), (x, y, 0.005 + 0.001 * _), label="rug", material=mat)
    return world
