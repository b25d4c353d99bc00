"""The built-in world kinds of scenarios (``world: {kind: ..., ...}``; a bare name is ``{kind: name}``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError, check_at_most, check_real_fields
from cufund.core.registry import Kind, register

from .builtin import corridor, empty, forest, imav2025_tunnel
from .vio_room import vio_room


@dataclass(frozen=True)
class NoParams:
    """This kind takes no parameters."""


@dataclass(frozen=True)
class ForestParams:
    """A seeded forest of tree trunks (:func:`cufund.worlds.builtin.forest`)."""

    seed: int = 0
    """Layout seed (independent of the scenario seed, so a layout can be flown with any noise)."""
    n_trees: int = 120
    """Number of trunks."""
    size: float = 40.0
    """Side of the square the trees stand in [m]."""
    clearing: float = 2.0
    """No tree within this distance of the origin [m]."""

    def __post_init__(self) -> None:
        for name in ("seed", "n_trees"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise ConfigError(f"world.{name} must be an integer >= 0, got {v!r}")
        check_real_fields(self, "world", positive=True, unit=" [m]", names=("size",))
        check_real_fields(self, "world", unit=" [m]", names=("clearing",))
        check_at_most(self, "world", n_trees=100_000, size=1e4)


@dataclass(frozen=True)
class CorridorParams:
    """A straight corridor along +x (:func:`cufund.worlds.builtin.corridor`)."""

    length: float = 30.0
    """[m]"""
    width: float = 2.0
    """[m]"""
    height: float = 2.5
    """[m]"""

    def __post_init__(self) -> None:
        check_real_fields(self, "world", positive=True, unit=" [m]")
        check_at_most(self, "world", length=1e4, width=1e3, height=1e3)


@dataclass(frozen=True)
class FileParams:
    """A world described in a YAML file (:func:`cufund.worlds.world_from_yaml`); a relative path is relative to
    the scenario file."""

    path: str = ""
    """The world file."""

    def __post_init__(self) -> None:
        if not isinstance(self.path, str) or not self.path:
            raise ConfigError(f"world.path must name a world YAML file, got {self.path!r}")


def _file(p: FileParams, ctx: BuildContext) -> Any:
    from .description import world_from_yaml

    path = Path(p.path)
    if not path.is_absolute() and ctx.base_dir is not None:
        path = Path(ctx.base_dir) / path
    if not path.is_file():
        raise ConfigError(f"world.path: no world file at {path}")
    return world_from_yaml(path)


register(Kind("world", "empty", NoParams, lambda p, ctx: empty(), None, "a 100 m x 100 m ground plane"))
register(
    Kind(
        "world",
        "imav2025_tunnel",
        NoParams,
        lambda p, ctx: imav2025_tunnel(),
        None,
        "the paper's IMAV 2025 tunnel: five 0.5 m x 1 m frames in a 12 x 8 x 4 m arena",
    )
)
register(
    Kind(
        "world",
        "forest",
        ForestParams,
        lambda p, ctx: forest(p.seed, p.n_trees, p.size, p.clearing),
        None,
        "a seeded forest of trunks",
    )
)
register(
    Kind(
        "world",
        "corridor",
        CorridorParams,
        lambda p, ctx: corridor(p.length, p.width, p.height),
        None,
        "a straight corridor",
    )
)
register(Kind("world", "file", FileParams, _file, None, "a world YAML file (world.path)"))


@dataclass(frozen=True)
class VioRoomParams:
    """The textured indoor room of :mod:`cufund.worlds.vio_room`."""

    seed: int = 0
    """Layout seed of its posters, rugs and crates."""

    def __post_init__(self) -> None:
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError(f"world.seed must be an integer >= 0, got {self.seed!r}")


register(
    Kind(
        "world",
        "vio_room",
        VioRoomParams,
        lambda p, ctx: vio_room(p.seed),
        None,
        "an 8 x 6 x 3 m textured room (posters, shelves, brick and concrete) for visual odometry",
    )
)
from . import search_forest  # noqa: E402, F401  (registers the world kind search_forest)
