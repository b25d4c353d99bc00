"""A wind field from a grid file, e.g. an exported CFD slice (docs/guides/atmosphere.md).

The file is a NumPy ``.npz`` archive of plain arrays (loaded with ``allow_pickle=False``: a pickled object is
refused) holding

- ``x`` (nx,), ``y`` (ny,), ``z`` (nz,): the grid's axes in the world frame (ENU) [m], each >= 2 finite, strictly
  increasing values;
- ``wind`` (nx, ny, nz, 3): the wind velocity at each node, world frame [m/s], finite.

The plant interpolates it trilinearly (``cpp/dynamics/atmosphere.cpp``); outside the grid's box the position is
clamped to the box (the nearest face's values). At most 2^24 nodes.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cufund.core.config import ConfigError

__all__ = ["MAX_NODES", "WindGrid", "load_wind_grid", "save_wind_grid"]

MAX_NODES = 1 << 24


@dataclass(frozen=True, eq=False)
class WindGrid:
    """A validated wind grid: axes ``x``, ``y``, ``z`` [m] and ``wind`` (nx, ny, nz, 3) [m/s]."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    wind: np.ndarray

    def __post_init__(self) -> None:
        for name in ("x", "y", "z"):
            a = np.asarray(getattr(self, name))
            if a.ndim != 1 or a.shape[0] < 2 or a.dtype.kind not in "fiu":
                raise ConfigError(f"wind grid: axis {name} must be a 1-D numeric array of >= 2 values, got {a.shape}")
            a = a.astype(float)
            if not np.all(np.isfinite(a)) or not np.all(np.diff(a) > 0):
                raise ConfigError(f"wind grid: axis {name} must be finite and strictly increasing [m]")
            object.__setattr__(self, name, a)
        shape = (self.x.size, self.y.size, self.z.size, 3)
        w = np.asarray(self.wind)
        if w.shape != shape or w.dtype.kind not in "fiu":
            raise ConfigError(
                f"wind grid: wind must be a numeric array of shape (nx, ny, nz, 3) = {shape}, got {w.shape}"
            )
        if self.x.size * self.y.size * self.z.size > MAX_NODES:
            raise ConfigError(f"wind grid: at most {MAX_NODES} nodes, got {self.x.size * self.y.size * self.z.size}")
        w = w.astype(float)
        if not np.all(np.isfinite(w)) or np.max(np.abs(w)) > 200.0:
            raise ConfigError("wind grid: wind must be finite and within +-200 m/s")
        object.__setattr__(self, "wind", np.ascontiguousarray(w))


def load_wind_grid(path: str | Path) -> WindGrid:
    """Reads and validates a ``.npz`` wind grid; a missing, malformed or hostile file raises :class:`ConfigError`."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"atmosphere.grid_file: no such file {str(path)!r}")
    try:
        with open(path, "rb") as fh:
            data = np.load(fh, allow_pickle=False)
            if not isinstance(data, np.lib.npyio.NpzFile):
                raise ConfigError(
                    f"atmosphere.grid_file: {str(path)!r} is a single array, not an .npz of x, y, z, wind"
                )
            with data:
                missing = [k for k in ("x", "y", "z", "wind") if k not in data.files]
                if missing:
                    raise ConfigError(
                        f"atmosphere.grid_file: {str(path)!r} lacks array {missing[0]!r} (needs x, y, z, wind)"
                    )
                arrays = {k: data[k] for k in ("x", "y", "z", "wind")}
    except ConfigError:
        raise
    except (ValueError, OSError, zipfile.BadZipFile, EOFError, KeyError) as e:
        raise ConfigError(f"atmosphere.grid_file: {str(path)!r} is not a readable .npz of plain arrays ({e})") from None
    try:
        return WindGrid(**arrays)
    except ConfigError as e:
        raise ConfigError(f"atmosphere.grid_file {str(path)!r}: {e}") from None


def save_wind_grid(path: str | Path, x: np.ndarray, y: np.ndarray, z: np.ndarray, wind: np.ndarray) -> None:
    """Writes a wind grid in the format :func:`load_wind_grid` reads (validated first)."""
    g = WindGrid(np.asarray(x), np.asarray(y), np.asarray(z), np.asarray(wind))
    np.savez(path, x=g.x, y=g.y, z=g.z, wind=g.wind)
