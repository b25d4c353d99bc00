"""Pinhole depth and RGB cameras rendered by ray casting, with optional radial-tangential distortion.

The camera frame C is mounted on the body with ``T_BC`` and is FLU like the body (x forward, y left,
z up). Images follow the optical convention: column u grows to the right, row v downwards, pixel
centres at integer (u, v), and (OpenCV) distortion (k1, k2, p1, p2, k3) maps undistorted normalised
coordinates to distorted ones.
"""

from __future__ import annotations

import dataclasses
import struct
import zlib
from pathlib import Path

import numpy as np

from cufund import _core
from cufund.core.messages import CameraImage  # noqa: F401 - re-exported: cameras' message
from cufund.geometry import Transform, quat_mul, quat_to_matrix
from cufund.worlds.world import World

# Optical frame O (x right, y down, z forward) -> camera frame C (x forward, y left, z up).
R_CO = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@dataclasses.dataclass(frozen=True)
class CameraIntrinsics:
    width: int
    """Image width [px]."""
    height: int
    """Image height [px]."""
    fx: float
    """Focal length in pixels along u [px]."""
    fy: float
    """Focal length in pixels along v [px]."""
    cx: float
    """Principal point u [px]."""
    cy: float
    """Principal point v [px]."""
    distortion: tuple[float, float, float, float, float] = (0.0, 0.0, 0.0, 0.0, 0.0)
    """Radial-tangential (k1, k2, p1, p2, k3), OpenCV's order."""

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            v = getattr(self, name)
            if (
                isinstance(v, bool)
                or not isinstance(v, (int, float, np.integer, np.floating))
                or not 1 <= v <= 100_000
                or int(v) != v
            ):
                raise ValueError(f"{name} must be a positive integer [px], got {v}")
            object.__setattr__(self, name, int(v))
        for name in ("fx", "fy", "cx", "cy"):
            if isinstance(getattr(self, name), bool) or not isinstance(
                getattr(self, name), (int, float, np.integer, np.floating)
            ):
                raise ValueError(f"{name} must be a real number [px], got {getattr(self, name)!r}")
        for name in ("fx", "fy"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a finite number > 0 [px], got {v}")
        for name in ("cx", "cy"):
            if not np.isfinite(getattr(self, name)):
                raise ValueError(f"{name} must be finite [px]")
        try:
            d = np.asarray(self.distortion, dtype=float)
        except (TypeError, ValueError):
            d = np.full(1, np.nan)  # reported below
        if d.shape != (5,) or not np.all(np.isfinite(d)):
            raise ValueError(f"distortion must be 5 finite numbers (k1, k2, p1, p2, k3), got {self.distortion!r}")
        object.__setattr__(self, "distortion", tuple(float(x) for x in d))

    @classmethod
    def from_fov(cls, width: int, height: int, hfov: float) -> CameraIntrinsics:
        """Square pixels, principal point at the image centre, horizontal field of view ``hfov`` [rad]."""
        if not 0 < hfov < np.pi:
            raise ValueError(f"hfov must be in (0, π) [rad], got {hfov}")
        f = (width / 2) / np.tan(hfov / 2)
        return cls(width, height, f, f, (width - 1) / 2, (height - 1) / 2)

    def project(self, p_O: np.ndarray) -> np.ndarray:
        """(N, 3) points in the optical frame -> (N, 2) distorted pixel coordinates (u, v)."""
        p_O = np.asarray(p_O, dtype=float)
        x, y = p_O[:, 0] / p_O[:, 2], p_O[:, 1] / p_O[:, 2]
        xd, yd = self._distort(x, y)
        return np.stack([self.fx * xd + self.cx, self.fy * yd + self.cy], 1)

    def _distort(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        k1, k2, p1, p2, k3 = self.distortion
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        return (
            x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x),
            y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y,
        )

    def pixel_directions(self) -> np.ndarray:
        """(H, W, 3) ray directions (x_n, y_n, 1) in the optical frame through each pixel centre,
        undistorted by fixed-point iteration (exact when distortion is zero)."""
        u, v = np.meshgrid(np.arange(self.width, dtype=float), np.arange(self.height, dtype=float))
        xd, yd = (u - self.cx) / self.fx, (v - self.cy) / self.fy
        x, y = xd.copy(), yd.copy()
        if any(self.distortion):
            k1, k2, p1, p2, k3 = self.distortion
            for _ in range(30):
                r2 = x * x + y * y
                radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
                x = (xd - 2 * p1 * x * y - p2 * (r2 + 2 * x * x)) / radial
                y = (yd - p1 * (r2 + 2 * y * y) - 2 * p2 * x * y) / radial
        return np.stack([x, y, np.ones_like(x)], -1)


def d435_depth() -> CameraIntrinsics:
    """RealSense D435-like depth stream at 640×480: fx = fy = 385 px, ≈ 79.5° × 63.9° field of view."""
    return CameraIntrinsics(640, 480, 385.0, 385.0, 319.5, 239.5)


def d435_rgb() -> CameraIntrinsics:
    """RealSense D435-like colour stream at 640×480: fx = fy = 615 px, ≈ 55.0° × 42.6° field of view."""
    return CameraIntrinsics(640, 480, 615.0, 615.0, 319.5, 239.5)


class _RayCamera:
    def __init__(self, intrinsics: CameraIntrinsics, T_BC: Transform | None, nthreads: int) -> None:
        self.intrinsics = intrinsics
        self.T_BC = T_BC or Transform()
        self.nthreads = int(nthreads)
        self._dirs_O = intrinsics.pixel_directions().reshape(-1, 3)

    def _rays(self, p_W: object, q_WB: object) -> tuple[np.ndarray, np.ndarray]:
        p = np.asarray(p_W, dtype=float)
        q = np.asarray(q_WB, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"p_W must be 3 finite numbers [m], got {p_W!r}")
        if q.shape != (4,) or not np.all(np.isfinite(q)) or np.linalg.norm(q) < 1e-9:
            raise ValueError(f"q_WB must be a non-zero quaternion [w, x, y, z], got {q_WB!r}")
        q = q / np.linalg.norm(q)
        R_WB = quat_to_matrix(q)
        R_WC = quat_to_matrix(quat_mul(q, np.array(self.T_BC.q)))
        p_WC = p + R_WB @ np.array(self.T_BC.t)
        R_WO = R_WC @ R_CO
        rays = np.empty((len(self._dirs_O), 6), np.float32)
        rays[:, :3] = p_WC
        rays[:, 3:] = self._dirs_O @ R_WO.T
        return rays, R_WO


def _scene_of(target: object) -> _core.lidar.RaycastScene:
    if isinstance(target, World):
        return target.raycast_scene
    if isinstance(target, _core.lidar.RaycastScene):
        return target
    raise ValueError(f"target must be a cufund.World or cufund.sensors.RaycastScene, got {type(target).__name__}")


class DepthCamera(_RayCamera):
    """Depth image along the optical axis [m], NaN where nothing is seen within [depth_min, depth_max].

    Noise: Gaussian with σ = ``noise_coeff`` × z² (stereo-like; 0 disables), seeded.
    """

    def __init__(
        self,
        intrinsics: CameraIntrinsics | None = None,
        T_BC: Transform | None = None,
        depth_min: float = 0.1,
        depth_max: float = 10.0,
        noise_coeff: float = 0.0,
        seed: int = 0,
        nthreads: int = 0,
    ) -> None:
        super().__init__(intrinsics or d435_depth(), T_BC, nthreads)
        if not (0 <= depth_min < depth_max and np.isfinite(depth_max)):
            raise ValueError(f"need 0 <= depth_min < depth_max < inf [m], got {depth_min}, {depth_max}")
        if not (np.isfinite(noise_coeff) and noise_coeff >= 0):
            raise ValueError(f"noise_coeff must be a finite number >= 0 [1/m], got {noise_coeff}")
        self.depth_min, self.depth_max, self.noise_coeff = float(depth_min), float(depth_max), float(noise_coeff)
        self.seed = seed
        self.reset()

    def reset(self) -> None:
        """Restarts the seeded depth-noise stream."""
        self._rng = np.random.default_rng(self.seed)

    def render(self, target: World | _core.lidar.RaycastScene, p_W: object, q_WB: object) -> np.ndarray:
        """(H, W) float32 depth image of ``target`` seen from body pose (p_W, q_WB)."""
        rays, _ = self._rays(p_W, q_WB)
        # direction z_O = 1, so the hit parameter is the depth along the optical axis
        z = _scene_of(target).cast_rays(rays, nthreads=self.nthreads)["t_hit"].astype(np.float64)
        if self.noise_coeff > 0:
            z = z + self._rng.standard_normal(z.shape) * self.noise_coeff * np.where(np.isfinite(z), z, 0.0) ** 2
        z[(z < self.depth_min) | (z > self.depth_max) | ~np.isfinite(z)] = np.nan
        h, w = self.intrinsics.height, self.intrinsics.width
        return z.reshape(h, w).astype(np.float32)


class RgbCamera(_RayCamera):
    """Colour image from each object's albedo with Lambert shading by a directional light.

    colour = albedo × (ambient + (1 - ambient) × |n · l|) for the world light direction ``light_W``;
    ``sky`` where nothing is hit.
    """

    def __init__(
        self,
        intrinsics: CameraIntrinsics | None = None,
        T_BC: Transform | None = None,
        light_W: object = (0.3, 0.2, 1.0),
        ambient: float = 0.3,
        sky: object = (0.55, 0.7, 0.9),
        nthreads: int = 0,
    ) -> None:
        super().__init__(intrinsics or d435_rgb(), T_BC, nthreads)
        light = np.asarray(light_W, dtype=float)
        if light.shape != (3,) or not np.all(np.isfinite(light)) or np.linalg.norm(light) == 0:
            raise ValueError(f"light_W must be a non-zero 3-vector, got {light_W!r}")
        if not 0.0 <= ambient <= 1.0:
            raise ValueError(f"ambient must be in [0, 1], got {ambient}")
        self.light_W = light / np.linalg.norm(light)
        self.ambient = float(ambient)
        self.sky = np.asarray(sky, dtype=float)

    def render(self, world: World, p_W: object, q_WB: object) -> np.ndarray:
        """(H, W, 3) uint8 RGB image of ``world`` seen from body pose (p_W, q_WB)."""
        if not isinstance(world, World):
            raise ValueError(f"world must be a cufund.World (it holds the colours), got {type(world).__name__}")
        rays, _ = self._rays(p_W, q_WB)
        hit = world.raycast_scene.cast_rays(rays, nthreads=self.nthreads)
        ids = hit["geometry_ids"].astype(np.int64)
        miss = ids == _core.lidar.INVALID_ID
        albedo = world.colors()[np.where(miss, -1, ids)]
        shade = self.ambient + (1 - self.ambient) * np.abs(hit["normals"] @ self.light_W)
        rgb = albedo * shade[:, None]
        rgb[miss] = self.sky
        h, w = self.intrinsics.height, self.intrinsics.width
        return (np.clip(rgb, 0, 1) * 255 + 0.5).astype(np.uint8).reshape(h, w, 3)


def save_png(path: str | Path, image: np.ndarray, depth_scale: float = 1000.0) -> None:
    """Writes an (H, W, 3) uint8 RGB image, or an (H, W) float depth image [m] as 16-bit grey in units
    of 1/``depth_scale`` m (millimetres by default; NaN -> 0), as a PNG file."""
    img = np.asarray(image)
    if img.ndim == 3 and img.shape[2] == 3 and img.dtype == np.uint8:
        color_type, bit_depth, rows = 2, 8, img
    elif img.ndim == 2 and np.issubdtype(img.dtype, np.floating):
        d = np.nan_to_num(img.astype(np.float64) * depth_scale, nan=0.0)
        rows = np.clip(np.round(d), 0, 65535).astype(">u2")
        color_type, bit_depth = 0, 16
    else:
        raise ValueError(f"image must be (H, W, 3) uint8 or (H, W) float depth, got {img.shape} {img.dtype}")
    h, w = rows.shape[:2]
    raw = b"".join(b"\x00" + rows[i].tobytes() for i in range(h))

    def chunk(tag: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, bit_depth, color_type, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b"")
    Path(path).write_bytes(png)
