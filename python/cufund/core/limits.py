"""Process-wide limits on inputs that a typo could otherwise turn into minutes of work or an exhausted machine.

Every limit fails fast with a :class:`~cufund.ConfigError` or :class:`ValueError` that names the limit to raise.
Read them with :func:`current`, change them with :func:`configure` (or temporarily with :func:`override`)::

    import cufund.core.limits
    cufund.core.limits.configure(grid_max_voxels=2**30)   # a bigger ESDF map on a big machine
"""

from __future__ import annotations

import contextlib
import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass

from cufund import _core

from .errors import ConfigError

__all__ = ["Limits", "configure", "current", "override"]


@dataclass(frozen=True)
class Limits:
    """The limits; every field is an integer >= 1."""

    yaml_max_aliases: int = 1000
    """Most alias uses (``*name``) one YAML file may hold: a "billion laughs" file expands far past this."""
    yaml_max_depth: int = 64
    """Deepest nesting of mappings and sequences in a YAML file."""
    yaml_max_bytes: int = 16 * 2**20
    """Largest YAML file read [bytes] (16 MiB)."""
    yaml_max_nodes: int = 1_000_000
    """Most values (scalars, lists, mappings) in a YAML document with its aliases expanded."""
    grid_max_voxels: int = 2**27
    """Most voxels of one ESDF map (about 20 bytes each: 2**27 is ~2.7 GB)."""
    batch_max_size: int = 2**24
    """Most vehicles of one QuadrotorBatch (256 bytes each: 2**24 is 4 GiB)."""
    mesh_max_segments: int = 4096
    """Most segments around a cylinder or sphere of a world description."""
    mesh_max_triangles: int = 2**24
    """Most triangles of one mesh loaded from a file or built from a primitive."""
    step_max_substeps: int = 1_000_000
    """Most RK4 sub-steps in one ``Quadrotor.step(dt)`` (dt / max_integration_step; 1e6 is 1000 s at 1 kHz)."""


_current = Limits()


def current() -> Limits:
    """The limits in force."""
    return _current


def configure(**changes: int) -> Limits:
    """Changes some limits (keyword = field of :class:`Limits`); returns the previous limits."""
    global _current
    names = {f.name for f in dataclasses.fields(Limits)}
    for key, value in changes.items():
        if key not in names:
            raise ConfigError(f"unknown limit {key!r}; known: {', '.join(sorted(names))}")
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ConfigError(f"limit {key} must be an integer >= 1, got {value!r}")
    if "step_max_substeps" in changes and changes["step_max_substeps"] > 10**9:
        raise ConfigError(f"limit step_max_substeps must be at most 1e9, got {changes['step_max_substeps']}")
    previous = _current
    _current = dataclasses.replace(_current, **changes)
    _core.dynamics.set_max_step_substeps(_current.step_max_substeps)
    return previous


@contextlib.contextmanager
def override(**changes: int) -> Iterator[Limits]:
    """``with override(grid_max_voxels=...):`` changes limits for the block, then restores them."""
    previous = configure(**changes)
    try:
        yield _current
    finally:
        configure(**dataclasses.asdict(previous))


_core.dynamics.set_max_step_substeps(_current.step_max_substeps)
