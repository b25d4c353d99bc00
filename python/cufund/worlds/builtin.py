"""Built-in worlds: ``load("imav2025_tunnel" | "empty" | "forest" | "corridor")``, and those the registered kinds add
(``tunnel_course``, from :mod:`cufund.missions`)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from cufund.core.registry import load_plugins

from .materials import Material
from .vio_room import vio_room
from .world import World

WALL = (0.75, 0.75, 0.72)
FLOOR = (0.45, 0.45, 0.45)


def textured(color: tuple[float, float, float], texture: str, scale: float, seed: int) -> Material:
    """A procedural material whose mean colour is about ``color`` (contrast 0.4: the pattern's mean is ~0.55), so
    that a textured world keeps the look of its plain colours."""
    k = 1.0 / (1.0 - 0.4 * 0.45)
    albedo = (min(1.0, color[0] * k), min(1.0, color[1] * k), min(1.0, color[2] * k))
    return Material(albedo, texture, scale=scale, contrast=0.4, seed=seed)


FLOOR_MATERIAL = textured(FLOOR, "concrete", 0.05, 11)
WALL_MATERIAL = textured(WALL, "concrete", 0.08, 12)


def arena(
    world: World, size: tuple[float, float, float], centre_xy: tuple[float, float] = (0.0, 0.0), wall: float = 0.1
) -> None:
    """Floor, ceiling and four walls of an indoor arena, inner size (sx, sy, sz) [m], floor at z = 0."""
    sx, sy, sz = size
    cx, cy = centre_xy
    floor, walls = FLOOR_MATERIAL, WALL_MATERIAL  # textures: only cameras see them
    world.add_box((sx + 2 * wall, sy + 2 * wall, wall), (cx, cy, -wall / 2), label="floor", color=FLOOR, material=floor)
    world.add_box(
        (sx + 2 * wall, sy + 2 * wall, wall), (cx, cy, sz + wall / 2), label="ceiling", color=WALL, material=walls
    )
    world.add_box((wall, sy, sz), (cx - (sx + wall) / 2, cy, sz / 2), label="wall", color=WALL, material=walls)
    world.add_box((wall, sy, sz), (cx + (sx + wall) / 2, cy, sz / 2), label="wall", color=WALL, material=walls)
    world.add_box((sx, wall, sz), (cx, cy - (sy + wall) / 2, sz / 2), label="wall", color=WALL, material=walls)
    world.add_box((sx, wall, sz), (cx, cy + (sy + wall) / 2, sz / 2), label="wall", color=WALL, material=walls)


def imav2025_tunnel() -> World:
    """IMAV 2025 tunnel challenge (paper §3): five frames with 0.5 m (y) × 1 m (z) openings, 0.5 m
    apart along x, from x = 0 to x = 2 m (2 m in total), in a 12 m × 8 m × 4 m arena.

    Each frame stands on the floor: its 5 cm bars surround an opening from z = 0.05 to 1.05 m, centred
    on y = 0. The vehicle starts around x = -2 m and flies along +x.
    """
    world = World("imav2025_tunnel")
    arena(world, (12.0, 8.0, 4.0), centre_xy=(1.0, 0.0))
    bar = 0.05
    for k in range(5):
        world.add_tunnel_frame((0.5 * k, 0.0, bar + 0.5), width=0.5, height=1.0, depth=bar, thickness=bar)
    return world


def empty() -> World:
    """Just a 100 m × 100 m ground plane at z = 0."""
    world = World("empty")
    world.add_plane((100.0, 100.0), (0.0, 0.0, 0.0), label="ground", color=FLOOR)
    return world


def forest(seed: int = 0, n_trees: int = 120, size: float = 40.0, clearing: float = 2.0) -> World:
    """Ground and ``n_trees`` trunks (cylinders, radius 0.1–0.3 m, height 4–10 m) at seeded uniform
    random positions in a ``size`` × ``size`` square, none within ``clearing`` of the origin."""
    from .primitives import _count

    n_trees = _count("n_trees", n_trees, 0, 100_000)
    for name, value in (("size", size), ("clearing", clearing)):
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float, np.integer, np.floating))
            or not np.isfinite(value)
            or value < 0
            or (name == "size" and value == 0)
        ):
            raise ValueError(f"{name} must be a finite number {'> 0' if name == 'size' else '>= 0'} [m], got {value!r}")
    if n_trees and clearing >= size / np.sqrt(2.0):
        raise ValueError(
            f"clearing must be < size / sqrt(2) = {size / np.sqrt(2.0):.3g} m so that trees fit in the "
            f"{size} m square outside it, got {clearing}"
        )
    world = World("forest")
    ground, bark = textured((0.35, 0.3, 0.2), "noise", 0.05, 21), textured((0.4, 0.25, 0.1), "bark", 0.3, 22)
    world.add_plane(
        (size + 10.0, size + 10.0), (0.0, 0.0, 0.0), label="ground", color=(0.35, 0.3, 0.2), material=ground
    )
    rng = np.random.default_rng(seed)
    placed = attempts = 0
    while placed < n_trees:
        attempts += 1
        if attempts > 1000 * (n_trees + 10):  # a sliver of room outside the clearing
            raise ValueError(
                f"could not place {n_trees} trees outside a clearing of {clearing} m in a {size} m square "
                f"(placed {placed} in {attempts - 1} draws); make the clearing smaller or the square larger"
            )
        x, y = rng.uniform(-size / 2, size / 2, 2)
        if np.hypot(x, y) < clearing:
            continue
        r, h = rng.uniform(0.1, 0.3), rng.uniform(4.0, 10.0)
        world.add_cylinder(r, h, (x, y, h / 2), label="tree", color=(0.4, 0.25, 0.1), segments=12, material=bark)
        placed += 1
    return world


def corridor(length: float = 30.0, width: float = 2.0, height: float = 2.5) -> World:
    """A straight corridor along +x from x = 0, with floor, ceiling and walls; open at both ends."""
    world = World("corridor")
    wall = 0.1
    cx = length / 2
    world.add_box((length, width + 2 * wall, wall), (cx, 0, -wall / 2), label="floor", color=FLOOR)
    world.add_box((length, width + 2 * wall, wall), (cx, 0, height + wall / 2), label="ceiling", color=WALL)
    world.add_box((length, wall, height), (cx, (width + wall) / 2, height / 2), label="wall", color=WALL)
    world.add_box((length, wall, height), (cx, -(width + wall) / 2, height / 2), label="wall", color=WALL)
    return world


BUILTIN: dict[str, Callable[..., World]] = {
    "imav2025_tunnel": imav2025_tunnel,
    "empty": empty,
    "forest": forest,
    "corridor": corridor,
    "vio_room": vio_room,
}


def load(name: str, **kwargs: object) -> World:
    """A built-in world by name (keyword arguments go to its builder, e.g. ``seed`` for forest),
    or a world described in a YAML file when ``name`` ends in .yaml / .yml."""
    if name.endswith((".yaml", ".yml")):
        from .description import world_from_yaml

        if kwargs:
            raise ValueError("a YAML world takes no keyword arguments")
        return world_from_yaml(name)
    if name not in BUILTIN:
        load_plugins()  # kinds of upper layers and plug-ins add their worlds (e.g. the tunnel course)
    if name not in BUILTIN:
        raise ValueError(f"unknown world {name!r}; built-in worlds are: {', '.join(BUILTIN)}")
    return BUILTIN[name](**kwargs)
