"""Pinhole depth and image cameras rendered by ray casting (Embree, the LiDAR's scene of the world).

The camera frame C is mounted on the body with ``T_BC`` and is FLU like the body (x forward, y left,
z up). Images follow the optical convention: column u grows to the right, row v downwards, pixel
centres at integer (u, v); lens models (radtan, equidistant) are :mod:`cufund.sensors.camera_models`'.

:class:`RgbCamera` shades each hit with its object's material (:mod:`cufund.worlds.materials`) under a sun and
ambient light, optionally with hard shadows (one shadow ray per pixel), sensor noise (shot + read), exposure with
motion blur and a rolling shutter; every option defaults to off (the flat look of plain colours).
"""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import numpy as np

from cufund import _core
from cufund.core.messages import CameraImage  # noqa: F401 - re-exported: cameras' message
from cufund.geometry import Transform, quat_mul, quat_to_matrix
from cufund.worlds.materials import material_table
from cufund.worlds.world import World

from .camera_models import R_CO, CameraIntrinsics

__all__ = ["R_CO", "CameraIntrinsics", "DepthCamera", "RgbCamera", "d435_depth", "d435_rgb", "save_png"]


def d435_depth() -> CameraIntrinsics:
    """RealSense D435-like depth stream at 640×480: fx = fy = 385 px, ≈ 79.5° × 63.9° field of view."""
    return CameraIntrinsics(640, 480, 385.0, 385.0, 319.5, 239.5)


def d435_rgb() -> CameraIntrinsics:
    """RealSense D435-like colour stream at 640×480: fx = fy = 615 px, ≈ 55.0° × 42.6° field of view."""
    return CameraIntrinsics(640, 480, 615.0, 615.0, 319.5, 239.5)


def _vec3(name: str, value: object) -> np.ndarray:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        a = np.full(1, np.nan)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be 3 finite numbers, got {value!r}")
    return a


class _RayCamera:
    def __init__(self, intrinsics: CameraIntrinsics, T_BC: Transform | None, nthreads: int) -> None:
        if not isinstance(intrinsics, CameraIntrinsics):
            raise ValueError(f"intrinsics must be a CameraIntrinsics, got {type(intrinsics).__name__}")
        if T_BC is not None and not isinstance(T_BC, Transform):
            raise ValueError(f"T_BC must be a cufund.geometry.Transform, got {type(T_BC).__name__}")
        self.intrinsics = intrinsics
        self.T_BC = T_BC or Transform()
        self.nthreads = int(nthreads)
        self._dirs_O = intrinsics.pixel_directions().reshape(-1, 3)

    @staticmethod
    def _pose(p_W: object, q_WB: object) -> tuple[np.ndarray, np.ndarray]:
        p = np.asarray(p_W, dtype=float)
        q = np.asarray(q_WB, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"p_W must be 3 finite numbers [m], got {p_W!r}")
        if q.shape != (4,) or not np.all(np.isfinite(q)) or np.linalg.norm(q) < 1e-9:
            raise ValueError(f"q_WB must be a non-zero quaternion [w, x, y, z], got {q_WB!r}")
        return p, q / np.linalg.norm(q)

    def _camera_pose(self, p: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(p_WC, R_WO) of the body pose (p, q)."""
        R_WB = quat_to_matrix(q)
        R_WC = quat_to_matrix(quat_mul(q, np.array(self.T_BC.q)))
        return p + R_WB @ np.array(self.T_BC.t), R_WC @ R_CO

    def _rays(self, p_W: object, q_WB: object) -> tuple[np.ndarray, np.ndarray]:
        p, q = self._pose(p_W, q_WB)
        p_WC, R_WO = self._camera_pose(p, q)
        rays = np.empty((len(self._dirs_O), 6), np.float32)
        rays[:, :3] = p_WC
        d = self._dirs_O  # R_WO d as columns times components (no BLAS matmul: its threads fight Embree's)
        rays[:, 3:] = d[:, :1] * R_WO[:, 0] + d[:, 1:2] * R_WO[:, 1] + d[:, 2:] * R_WO[:, 2]
        return rays, R_WO

    def _row_poses(
        self, p: np.ndarray, q: np.ndarray, v_W: np.ndarray, w_B: np.ndarray, row_dt: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(p_WO (H, 3), R_WO (H, 3, 3)) of each row r, taken at the pose propagated ``row_dt[r]`` seconds from
        (p, q) at constant world velocity ``v_W`` and body rate ``w_B``."""
        h = self.intrinsics.height
        if not (np.any(row_dt) and (np.any(v_W) or np.any(w_B))):  # every row at (p, q)
            p_WC, R_WO = self._camera_pose(p, q)
            return np.broadcast_to(p_WC, (h, 3)), np.broadcast_to(R_WO, (h, 3, 3))
        # every row at once: q_r = q exp(w_B dt_r) (the rotation vector's exponential), p_r = p + v_W dt_r
        phi = w_B[None, :] * row_dt[:, None]
        angle = np.linalg.norm(phi, axis=1)
        k = np.where(angle > 1e-12, np.sin(angle / 2) / np.where(angle > 1e-12, angle, 1.0), 0.5)
        dq = np.column_stack([np.cos(angle / 2), phi * k[:, None]])
        q_rows = _quat_mul_rows(np.broadcast_to(q, (h, 4)), dq)
        R_WB = _quat_to_matrix_rows(q_rows)
        R_WO = R_WB @ (self.T_BC.R @ R_CO)  # (H, 3, 3) @ (3, 3): batched 3x3 products, not one BLAS call
        p_WC = p + v_W * row_dt[:, None] + np.einsum("hij,j->hi", R_WB, np.array(self.T_BC.t))
        return p_WC, R_WO


def _quat_mul_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise Hamilton products of (N, 4) quaternions [w, x, y, z]."""
    w1, x1, y1, z1 = a.T
    w2, x2, y2, z2 = b.T
    return np.column_stack(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


def _quat_to_matrix_rows(q: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices of (N, 4) unit quaternions [w, x, y, z]."""
    w, x, y, z = q.T
    return np.stack(
        [
            np.column_stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)]),
            np.column_stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)]),
            np.column_stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]),
        ],
        axis=1,
    )


def _scene_of(target: object) -> _core.lidar.RaycastScene:
    if isinstance(target, World):
        return target.raycast_scene
    if isinstance(target, _core.lidar.RaycastScene):
        return target
    raise ValueError(f"target must be a cufund.World or cufund.sensors.RaycastScene, got {type(target).__name__}")


def _ids(geometry_ids: np.ndarray) -> np.ndarray:
    ids = geometry_ids.astype(np.int64)
    ids[geometry_ids == _core.lidar.INVALID_ID] = -1
    return ids.astype(np.int32)


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

    def render(
        self, target: World | _core.lidar.RaycastScene, p_W: object, q_WB: object, want_ids: bool = False
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
        """(H, W) float32 depth image of ``target`` seen from body pose (p_W, q_WB). With ``want_ids`` (``target``
        a World): (depth, ids, labels), ``ids`` (H, W) int32 object id per pixel (-1: nothing hit; also where the
        depth is out of range) and ``labels`` the world's object labels by id."""
        if want_ids and not isinstance(target, World):
            raise ValueError(f"want_ids needs a cufund.World (it holds the labels), got {type(target).__name__}")
        rays, _ = self._rays(p_W, q_WB)
        # direction z_O = 1, so the hit parameter is the depth along the optical axis
        hit = _scene_of(target).cast_rays(rays, nthreads=self.nthreads)
        z = hit["t_hit"].astype(np.float64)
        if self.noise_coeff > 0:
            z = z + self._rng.standard_normal(z.shape) * self.noise_coeff * np.where(np.isfinite(z), z, 0.0) ** 2
        z[(z < self.depth_min) | (z > self.depth_max) | ~np.isfinite(z)] = np.nan
        h, w = self.intrinsics.height, self.intrinsics.width
        depth = z.reshape(h, w).astype(np.float32)
        if not want_ids:
            return depth
        assert isinstance(target, World)
        ids = _ids(hit["geometry_ids"]).reshape(h, w)
        ids[np.isnan(depth)] = -1
        return depth, ids, tuple(target.labels())


class RgbCamera(_RayCamera):
    """Colour (or grey) image of a world's materials lit by a sun and ambient light.

    colour = albedo × (ambient + (1 - ambient) × direct), ``sky`` where nothing is hit. Without ``shadows`` the
    direct term is |n · l| for the unit direction to the sun ``light_W`` (two-sided, no occlusion: the flat look of
    earlier versions); with ``shadows`` it is max(0, n · l) with n facing the camera, and 0 where a shadow ray from
    the hit towards the sun hits anything. The albedo is the object's material at the hit (its ``color`` when it
    has none).

    Sensor model (all off by default):

    - ``exposure_s`` > 0 with a moving pose (``render(..., v_W=, w_B=)``): the mean of ``blur_samples`` images at
      poses spread evenly over the exposure, centred on the render time (motion blur). Brightness does not depend
      on the exposure (auto exposure).
    - ``line_time_s`` > 0: rolling shutter, row r is exposed ``(r - (H - 1) / 2) × line_time_s`` after the
      render time (the middle of the readout is the frame's stamp), see :meth:`row_times`.
    - ``full_well_e`` > 0: shot noise, Poisson in electrons with full scale = ``full_well_e``; ``read_noise_dn``:
      Gaussian read noise σ [8-bit digital numbers]; seeded (``seed``, :meth:`reset`).
    - ``grayscale``: (H, W) uint8 luma (0.299 R + 0.587 G + 0.114 B) instead of (H, W, 3) RGB.
    """

    def __init__(
        self,
        intrinsics: CameraIntrinsics | None = None,
        T_BC: Transform | None = None,
        light_W: object = (0.3, 0.2, 1.0),
        ambient: float = 0.3,
        sky: object = (0.55, 0.7, 0.9),
        nthreads: int = 0,
        *,
        shadows: bool = False,
        grayscale: bool = False,
        exposure_s: float = 0.0,
        blur_samples: int = 5,
        line_time_s: float = 0.0,
        full_well_e: float = 0.0,
        read_noise_dn: float = 0.0,
        seed: int = 0,
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
        for name, v in (
            ("exposure_s", exposure_s),
            ("line_time_s", line_time_s),
            ("full_well_e", full_well_e),
            ("read_noise_dn", read_noise_dn),
        ):
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not 0 <= v < 1e9:
                raise ValueError(f"{name} must be a finite number >= 0, got {v!r}")
        if (
            isinstance(blur_samples, bool)
            or not isinstance(blur_samples, (int, np.integer))
            or not 1 <= blur_samples <= 64
        ):
            raise ValueError(f"blur_samples must be an integer in [1, 64], got {blur_samples!r}")
        self.shadows, self.grayscale = bool(shadows), bool(grayscale)
        self.exposure_s, self.blur_samples, self.line_time_s = float(exposure_s), int(blur_samples), float(line_time_s)
        self.full_well_e, self.read_noise_dn = float(full_well_e), float(read_noise_dn)
        self.seed = seed
        self._dirs_O32 = np.ascontiguousarray(self._dirs_O, dtype=np.float32)
        self._table_key: tuple | None = None
        self.reset()

    def reset(self) -> None:
        """Restarts the seeded sensor-noise stream."""
        self._rng = np.random.default_rng(self.seed)

    def row_times(self, t: float) -> np.ndarray:
        """(H,) exposure-centre time of each row [s] of a frame stamped ``t`` (all ``t`` for a global shutter)."""
        return t + self._row_dt()

    def _row_dt(self) -> np.ndarray:
        h = self.intrinsics.height
        return (np.arange(h) - (h - 1) / 2) * self.line_time_s

    def render(
        self,
        world: World,
        p_W: object,
        q_WB: object,
        want_ids: bool = False,
        v_W: object = None,
        w_B: object = None,
    ) -> np.ndarray | tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
        """(H, W, 3) uint8 RGB (or (H, W) grey) image of ``world`` seen from body pose (p_W, q_WB) at the frame's
        stamp; ``v_W`` [m/s] and ``w_B`` [rad/s] (world velocity, body rates) move the pose over the exposure and
        readout. With ``want_ids``: (image, ids, labels), ``ids`` (H, W) int32 object id per pixel (-1: nothing)
        of the middle sub-frame (the stamp's pose for an odd ``blur_samples``) and ``labels`` the world's object
        labels by id (``labels[ids]``)."""
        if not isinstance(world, World):
            raise ValueError(f"world must be a cufund.World (it holds the colours), got {type(world).__name__}")
        p, q = self._pose(p_W, q_WB)
        moving = v_W is not None or w_B is not None
        v = _vec3("v_W", v_W) if v_W is not None else np.zeros(3)
        w = _vec3("w_B", w_B) if w_B is not None else np.zeros(3)
        moving = moving and bool(np.any(v) or np.any(w))
        n = self.blur_samples if (moving and self.exposure_s > 0) else 1
        row_dt = self._row_dt()
        h, wd = self.intrinsics.height, self.intrinsics.width
        acc: np.ndarray | None = None
        ids_out = None
        for k in range(n):
            dt = self.exposure_s * ((k + 0.5) / n - 0.5) if n > 1 else 0.0
            lin, ids = self._shade(world, *self._row_poses(p, q, v, w, row_dt + dt))
            acc = lin if acc is None else acc + lin
            if k == n // 2:
                ids_out = ids
        assert acc is not None
        lin = acc / np.float32(n) if n > 1 else acc
        if self.grayscale:
            # weighted sum, not a matmul: BLAS's threads fight the renderer's for the cores
            lin = lin[:, 0] * np.float32(0.299) + lin[:, 1] * np.float32(0.587) + lin[:, 2] * np.float32(0.114)
        if self.full_well_e > 0:
            lam = np.clip(lin, 0.0, 1.0) * self.full_well_e
            lin = self._rng.poisson(lam) / self.full_well_e
        if self.read_noise_dn > 0:
            lin = lin + self._rng.standard_normal(lin.shape) * (self.read_noise_dn / 255.0)
        img = (np.clip(lin, 0, 1) * np.float32(255) + np.float32(0.5)).astype(np.uint8)
        img = img.reshape(h, wd) if self.grayscale else img.reshape(h, wd, 3)
        if not want_ids:
            return img
        assert ids_out is not None
        return img, ids_out.reshape(h, wd), tuple(world.labels())

    def _shade(self, world: World, row_p: np.ndarray, row_R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) linear colour and (N,) int32 object ids of the view with rows at poses (row_p, row_R), rendered
        in C++ (cufund._core.render); image-textured objects are coloured here through their UVs."""
        scene = world.raycast_scene
        if self._table_key is None or self._table_key[0] is not scene:
            self._table_key = (scene, *material_table(world.objects))
        _, table, tiles, external = self._table_key
        h, w = self.intrinsics.height, self.intrinsics.width
        out = _core.render.render_image(
            scene,
            self._dirs_O32,
            row_p,
            row_R,
            w,
            h,
            table,
            tiles,
            self.light_W,
            self.ambient,
            self.shadows,
            self.sky,
            self.nthreads,
        )
        rgb, ids = out["rgb"], out["ids"]
        if external:
            sel = np.nonzero(np.isin(ids, external))[0]
            if len(sel):
                rgb[sel] = self._image_albedo(world, sel, row_p, row_R) * out["shade"][sel, None]
        return rgb, ids

    def _image_albedo(self, world: World, sel: np.ndarray, row_p: np.ndarray, row_R: np.ndarray) -> np.ndarray:
        """(M, 3) albedo of image-textured objects at pixels ``sel`` (their rays cast again for UVs)."""
        rows = sel // self.intrinsics.width
        rays = np.empty((len(sel), 6), np.float32)
        rays[:, :3] = row_p[rows]
        rays[:, 3:] = np.einsum("nij,nj->ni", row_R[rows], self._dirs_O[sel])
        hit = world.raycast_scene.cast_rays(rays, nthreads=self.nthreads)
        ids = _ids(hit["geometry_ids"])
        out = np.zeros((len(sel), 3))
        for oid in np.unique(ids[ids >= 0]):
            obj = world.objects[oid]
            k = np.nonzero(ids == oid)[0]
            t = hit["t_hit"][k].astype(np.float64)
            p_W = rays[k, :3] + rays[k, 3:] * t[:, None]
            n_W = hit["normals"][k].astype(np.float64)
            mat = obj.material
            if mat is None:
                out[k] = obj.color
                continue
            uv = None
            if obj.uvs is not None:
                prim = hit["primitive_ids"][k].astype(np.int64)
                b = hit["primitive_uvs"][k].astype(np.float64)
                tri = obj.triangles[prim]
                uv = (
                    (1 - b[:, :1] - b[:, 1:]) * obj.uvs[tri[:, 0]]
                    + b[:, :1] * obj.uvs[tri[:, 1]]
                    + b[:, 1:] * obj.uvs[tri[:, 2]]
                )
            out[k] = mat.albedo_at(p_W, n_W, uv)
        return out


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
