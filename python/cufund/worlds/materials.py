"""Surface materials of world objects for the cameras: an albedo colour, a seeded procedural texture (checker,
noise, brick, bark, concrete) or a PNG image texture.

A texture is a scalar pattern f in [0, 1] that mixes two colours: ``albedo`` where f = 1 and ``albedo2`` where
f = 0 (default ``albedo * (1 - contrast)``). Procedural textures are evaluated at the world point of each hit,
projected on the plane across the dominant axis of its normal (tri-planar mapping: exact on axis-aligned faces);
``scale`` is the texture's feature size [m] (checker square, brick length, noise cell). An image texture is
read through the mesh's UV coordinates (OBJ ``vt``), or tiled every ``scale`` metres when the mesh has none.

Materials only colour camera images: LiDAR returns, depth images and collisions do not depend on them.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path
from typing import Any

import numpy as np

TEXTURES = ("none", "checker", "noise", "brick", "bark", "concrete", "image")
MAX_IMAGE_SIDE = 8192
"""Largest side of an image texture [px]."""
_TILE = 256  # the procedural noise tile: _TILE x _TILE texels, periodic (one for all seeds: it stays in cache)
_CELLS = 32  # base noise cells across a tile


def _rgb(name: str, value: object) -> tuple[float, float, float]:
    try:
        c = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        c = np.full(1, np.nan)
    if c.shape != (3,) or not np.all((c >= 0.0) & (c <= 1.0)):
        raise ValueError(f"material.{name} must be 3 numbers in [0, 1] (RGB), got {value!r}")
    return (float(c[0]), float(c[1]), float(c[2]))


@dataclasses.dataclass(frozen=True)
class Material:
    """How a surface looks to a camera (see the module's docstring)."""

    albedo: tuple[float, float, float] = (0.7, 0.7, 0.7)
    """Diffuse colour (RGB in [0, 1]); the bright colour of a texture."""
    texture: str = "none"
    """none, checker, noise, brick, bark, concrete or image."""
    scale: float = 0.5
    """Texture feature size [m]: checker square, brick length, noise cell; an image's tile size without UVs."""
    contrast: float = 0.6
    """Dark colour = albedo × (1 - contrast) unless ``albedo2`` is given; in [0, 1]."""
    albedo2: tuple[float, float, float] | None = None
    """The texture's dark colour (checker's other squares, brick mortar), RGB in [0, 1]."""
    seed: int = 0
    """Seed of a procedural texture."""
    image: str = ""
    """PNG file of an image texture (texture: image)."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "albedo", _rgb("albedo", self.albedo))
        if self.albedo2 is not None:
            object.__setattr__(self, "albedo2", _rgb("albedo2", self.albedo2))
        if self.texture not in TEXTURES:
            raise ValueError(f"material.texture must be one of {', '.join(TEXTURES)}, got {self.texture!r}")
        for name, lo, hi in (("scale", 1e-4, 1e4), ("contrast", 0.0, 1.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not lo <= v <= hi:
                raise ValueError(f"material.{name} must be a number in [{lo:g}, {hi:g}], got {v!r}")
            object.__setattr__(self, name, float(v))
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or not 0 <= self.seed < 2**32:
            raise ValueError(f"material.seed must be an integer in [0, 2^32), got {self.seed!r}")
        if self.texture == "image":
            if not isinstance(self.image, (str, Path)) or not str(self.image):
                raise ValueError("material.image must name a PNG file when texture is image")
            object.__setattr__(self, "image", str(self.image))
            _load_image(self.image)  # fails now, naming the file, rather than at the first frame
        elif self.image:
            raise ValueError(f"material.image is only read with texture: image, got texture {self.texture!r}")

    @classmethod
    def of(cls, value: Any, base_dir: str | Path | None = None) -> Material:
        """A Material from itself or a mapping of its fields (a relative ``image`` is taken from ``base_dir``)."""
        if isinstance(value, Material):
            return value
        if not isinstance(value, dict):
            raise ValueError(f"material must be a mapping of {', '.join(f.name for f in dataclasses.fields(cls))}")
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(value) - names)
        if unknown:
            raise ValueError(f"unknown key {unknown[0]!r} in material; expected one of: {', '.join(sorted(names))}")
        value = dict(value)
        if base_dir is not None and isinstance(value.get("image"), str) and value["image"]:
            p = Path(value["image"])
            value["image"] = str(p if p.is_absolute() else Path(base_dir) / p)
        return cls(**value)

    @property
    def dark(self) -> np.ndarray:
        return np.asarray(self.albedo2 if self.albedo2 is not None else np.asarray(self.albedo) * (1 - self.contrast))

    def albedo_at(
        self, p_W: np.ndarray, n_W: np.ndarray, uv: np.ndarray | None = None, offset: np.ndarray | None = None
    ) -> np.ndarray:
        """(N, 3) colour at world points ``p_W`` (N, 3) with normals ``n_W`` (N, 3); ``uv`` (N, 2) texture
        coordinates of an image texture on a mesh with UVs; ``offset`` (N, 2) shifts procedural textures [m]
        (so that objects sharing a material do not look alike)."""
        n = len(p_W)
        bright = np.asarray(self.albedo)
        if self.texture == "none" or n == 0:
            return np.broadcast_to(bright, (n, 3)).copy()
        if self.texture == "image":
            img = _load_image(self.image)
            if uv is None:
                uv = planar_coords(p_W, n_W) / self.scale
            return sample_image(img, uv) * bright
        a, b = (planar_coords(p_W, n_W) + (0.0 if offset is None else offset)).T
        f = self.pattern(a / self.scale, b / self.scale)
        return self.dark + (bright - self.dark) * f[:, None]

    def pattern(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """The texture's value in [0, 1] at plane coordinates (a, b) in units of ``scale`` (the renderer's own
        code, cpp/render/textures.cpp)."""
        from cufund import _core

        tile = _noise_tile() if self.texture in _TILED else np.zeros((1, 1), np.float32)
        return np.asarray(
            _core.render.pattern(
                TEXTURE_CODES[self.texture], np.ravel(a).astype(float), np.ravel(b).astype(float), tile, self.seed
            )
        ).reshape(np.shape(a))


TEXTURE_CODES = {"none": 0, "checker": 1, "noise": 2, "brick": 3, "bark": 4, "concrete": 5, "image": 6}
"""The renderer's texture codes (cpp/render/textures.h)."""
_TILED = ("noise", "brick", "bark", "concrete")


def material_table(objects: Any) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """The renderer's material rows of world objects (by id), their noise tiles and the ids of objects with
    image textures (coloured by the caller): (table (G, 13) float64, tiles (T, S, S) float32, external ids)."""
    rows, external = [], []
    for obj in objects:
        m = obj.material
        row = np.zeros(13)
        if m is None:
            row[1:4] = row[4:7] = obj.color
            row[7] = 1.0
            row[9] = -1
        else:
            row[0] = TEXTURE_CODES[m.texture]
            row[1:4] = m.albedo
            row[4:7] = m.dark
            row[7] = m.scale
            row[8] = m.seed
            row[9] = -1
            if m.texture in _TILED:
                row[9] = 0  # the one noise tile; the seed picks where it is read
            if m.texture == "image":
                external.append(obj.id)
            # each object's texture shifted by its id, so objects sharing a material do not repeat one another
            row[10:12] = (obj.id * np.array([7.31, 3.17])) % 97.0
        rows.append(row)
    tiles = _noise_tile()[None]
    return np.array(rows, dtype=float).reshape(-1, 13), tiles, external


def planar_coords(p_W: np.ndarray, n_W: np.ndarray) -> np.ndarray:
    """(N, 2) coordinates of points on the plane across the dominant axis of their normals [m]: (y, z) on faces
    facing x, (x, z) facing y, (x, y) facing z."""
    axis = np.argmax(np.abs(n_W), axis=1)
    out = np.empty((len(p_W), 2))
    out[:, 0] = np.where(axis == 0, p_W[:, 1], p_W[:, 0])
    out[:, 1] = np.where(axis == 2, p_W[:, 1], p_W[:, 2])
    return out


@functools.lru_cache(maxsize=1)
def _noise_tile() -> np.ndarray:
    """The periodic _TILE x _TILE value-noise tile in [0, 1]: octaves of _CELLS, 2 _CELLS, ... cells (fixed: a
    texture's seed picks where it reads the tile)."""
    rng = np.random.default_rng(20251127)
    tile = np.zeros((_TILE, _TILE))
    amp, total = 1.0, 0.0
    cells = _CELLS
    while cells <= _TILE // 2:
        grid = rng.random((cells, cells))
        x = np.arange(_TILE) * cells / _TILE
        i0 = np.floor(x).astype(int)
        t = x - i0
        t = t * t * (3 - 2 * t)  # smoothstep
        i1 = (i0 + 1) % cells
        rows = grid[i0] * (1 - t)[:, None] + grid[i1] * t[:, None]
        tile += amp * (rows[:, i0] * (1 - t) + rows[:, i1] * t)
        total += amp
        amp *= 0.6
        cells *= 2
    tile /= total
    lo, hi = np.percentile(tile, (1, 99))
    return np.clip((tile - lo) / (hi - lo), 0.0, 1.0).astype(np.float32)


def sample_image(img: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(N, 3) float32 colour in [0, 1] of an (H, W, 3) uint8 image at texture coordinates ``uv`` (N, 2): u to the
    right, v up from the bottom row (OBJ's convention), repeating outside [0, 1); nearest texel."""
    h, w = img.shape[:2]
    u = np.mod(uv[:, 0], 1.0)
    v = np.mod(uv[:, 1], 1.0)
    col = np.minimum((u * w).astype(np.int64), w - 1)
    row = np.minimum(((1.0 - v) * h).astype(np.int64), h - 1)
    return img[row, col].astype(np.float32) / np.float32(255.0)


@functools.lru_cache(maxsize=32)
def _load_image(path: str) -> np.ndarray:
    """An image texture as (H, W, 3) uint8 (3 bytes a texel: a 8192 x 8192 PNG of a few kB is 200 MB cached, not
    800 MB as float32); a clear error for anything but a readable PNG."""
    from PIL import Image

    p = Path(path)
    if not p.is_file():
        raise ValueError(f"material.image: no image file at {path!r}")
    try:
        with Image.open(p) as im:
            if im.format != "PNG":
                raise ValueError(f"material.image {path!r} must be a PNG file, got {im.format}")
            w, h = im.size
            if not (1 <= w <= MAX_IMAGE_SIDE and 1 <= h <= MAX_IMAGE_SIDE):
                raise ValueError(
                    f"material.image {path!r} must be between 1x1 and {MAX_IMAGE_SIDE}x{MAX_IMAGE_SIDE} px, got {w}x{h}"
                )
            arr = np.asarray(im.convert("RGB"), dtype=np.uint8)
    except ValueError:
        raise
    except Exception as e:  # Pillow raises many kinds on a hostile file (UnidentifiedImageError, OSError,
        # SyntaxError, struct.error, EOFError, DecompressionBombError, ...): each is "not a readable PNG"
        raise ValueError(f"material.image {path!r} is not a readable PNG: {type(e).__name__}: {e}") from None
    if arr.shape != (h, w, 3):
        raise ValueError(f"material.image {path!r} decoded to shape {arr.shape}, expected ({h}, {w}, 3)")
    return arr


def image_texture(path: str | Path) -> np.ndarray:
    """The decoded (H, W, 3) float32 image in [0, 1] of a PNG texture (its uint8 texels cached)."""
    return _load_image(str(path)).astype(np.float32) / np.float32(255.0)
