"""The ``search_forest`` world: a seeded forest of trunks (:func:`cufund.worlds.builtin.forest`) with K people
(:mod:`cufund.worlds.labelled_objects`) standing or lying at random on free ground, some of them right beside a
trunk (partly hidden behind it from most directions): what the ``search`` mission looks for. The people are
truth: only the scenario's metrics read them (:func:`people_positions`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError, check_at_most, check_real_fields
from cufund.core.registry import Kind, register

from .builtin import forest
from .labelled_objects import scatter
from .world import World

__all__ = ["SearchForestParams", "people_positions", "search_forest"]


@dataclass(frozen=True)
class SearchForestParams:
    """A forest with ``people`` people in it (:func:`search_forest`). Lengths [m]."""

    seed: int | None = None
    """Layout seed of the trees and the people; null: the scenario's seed (``--seed K`` flies layout K)."""
    n_trees: int = 150
    """Number of trunks (4-10 m tall)."""
    size: float = 40.0
    """Side of the square the trees stand in, centred on the origin [m]."""
    clearing: float = 3.0
    """No tree within this distance of the origin (the take-off spot) [m]."""
    people: int = 5
    """How many people are placed."""
    margin: float = 4.0
    """People stand at least this far inside the square's edges [m]."""
    beside_trees: float = 0.4
    """Share of the people placed within ``beside_m`` of a trunk (partly occluded) [-]."""
    beside_m: float = 1.0
    """How close to its trunk such a person stands (the square around the trunk's axis, half side) [m]."""
    separation: float = 4.0
    """People stand at least about this far apart (the centres of the squares they are drawn in) [m]."""

    def __post_init__(self) -> None:
        for name in ("n_trees", "people"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise ConfigError(f"world.{name} must be an integer >= 0, got {v!r}")
        s = self.seed
        if s is not None and (isinstance(s, bool) or not isinstance(s, int) or s < 0):
            raise ConfigError(f"world.seed must be an integer >= 0 or null (the scenario's seed), got {s!r}")
        check_real_fields(self, "world", positive=True, unit=" [m]", names=("size", "beside_m"))
        check_real_fields(self, "world", unit=" [m]", names=("clearing", "margin", "separation"))
        check_at_most(self, "world", n_trees=100_000, size=1e4, people=1000)
        b = self.beside_trees
        if isinstance(b, bool) or not isinstance(b, (int, float)) or not 0.0 <= b <= 1.0:
            raise ConfigError(f"world.beside_trees must be a share in [0, 1], got {b!r}")
        if not 0 <= self.margin < self.size / 2:
            raise ConfigError(f"world.margin must be in [0, size / 2 = {self.size / 2:g}) [m], got {self.margin!r}")


def search_forest(
    seed: int = 0,
    n_trees: int = 150,
    size: float = 40.0,
    clearing: float = 3.0,
    people: int = 5,
    margin: float = 4.0,
    beside_trees: float = 0.4,
    beside_m: float = 1.0,
    separation: float = 4.0,
) -> World:
    """The forest of ``seed`` and ``people`` people: the first round(``beside_trees`` x ``people``) each on free
    ground within ``beside_m`` of a trunk drawn at random (among those inside the margin), the others on free
    ground within 0.5 m of a point drawn uniformly at least ``margin`` inside the square
    (:func:`~cufund.worlds.labelled_objects.scatter`: random pose, height, colour and heading; one in ten lying).
    The trunks and points drawn are at least ``separation`` apart. A ``ValueError`` if fewer than ``people``
    fit."""
    world = forest(seed, n_trees, size, clearing)
    world.name = "search_forest"
    rng = np.random.default_rng([seed, 0x5EA8C4])  # the people's own stream: the trees are forest(seed)'s
    lo, hi = -size / 2 + margin, size / 2 - margin
    inside = [
        o
        for o in world.objects
        if o.label == "tree" and all(lo + beside_m <= c <= hi - beside_m for c in o.vertices.mean(0)[:2])
    ]
    n_beside = round(beside_trees * people) if inside else 0
    centres: list[np.ndarray] = []
    for k in range(people):
        for _ in range(200):
            if k < n_beside:
                c, half = inside[int(rng.integers(len(inside)))].vertices.mean(0)[:2], beside_m
            else:
                c, half = rng.uniform(lo, hi, 2), 0.5
            if all(np.linalg.norm(c - o) >= separation for o in centres):
                region = ((c[0] - half, c[0] + half), (c[1] - half, c[1] + half))
                if scatter(world, rng, 1, kinds=("person",), region=region, clearance=0.1):
                    centres.append(c)
                    break
    placed = len(centres)
    if placed < people:
        raise ValueError(f"could place only {placed} of {people} people on free ground in the forest")
    return world


def people_positions(world: World) -> np.ndarray:
    """(K, 3) centre of each object labelled ``person`` (the middle of its axis-aligned bounds) [m]: the search's
    ground truth (metrics only)."""
    rows = [0.5 * (o.vertices.min(0) + o.vertices.max(0)) for o in world.objects if o.label == "person"]
    return np.array(rows, dtype=float).reshape(-1, 3)


def _build(p: SearchForestParams, ctx: BuildContext) -> Any:
    try:
        return search_forest(
            ctx.seed if p.seed is None else p.seed,
            p.n_trees,
            p.size,
            p.clearing,
            p.people,
            p.margin,
            p.beside_trees,
            p.beside_m,
            p.separation,
        )
    except ValueError as e:
        raise ConfigError(f"world: {e}") from None


register(
    Kind(
        "world",
        "search_forest",
        SearchForestParams,
        _build,
        None,
        "a seeded forest of trunks with K people at random on free ground, some beside a trunk (the search's)",
    )
)
