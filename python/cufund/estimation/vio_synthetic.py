"""Synthetic visual-inertial data for developing and testing the VIO without the simulator: a textured box room
rendered by exact ray casting (numpy + ``cv2.remap``), an analytic trajectory and the IMU samples it implies.

Not flight software: the tests and ``benchmarks/bench_vio.py`` use it to give :class:`VioCore` stereo images and
IMU samples whose truth is known in closed form. The room's faces are planes x = +-half_x, y = +-half_y, z = 0,
z = height; each face carries a seeded multi-scale noise texture (corners at every scale), or a flat grey when it
is listed in ``textureless``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np

from cufund.geometry import homogeneous, quat_from_matrix

from .vio_params import VioCamera

__all__ = ["TexturedRoom", "Trajectory", "SyntheticRun", "hover_then", "synthesize", "rotation_zyx"]

_R_CO = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
_FACES = ("+x", "-x", "+y", "-y", "floor", "ceiling")


def _texture(rng: np.random.Generator, n: int) -> np.ndarray:
    """A (n, n) uint8 texture: blurred noise at several scales (blobs and corners from 4 to n/8 texels)."""
    acc = np.zeros((n, n), np.float32)
    for cells, weight in ((8, 1.0), (32, 0.8), (128, 0.6), (n // 4, 0.4)):
        small = rng.random((cells, cells)).astype(np.float32)
        acc += weight * np.asarray(
            cv2.resize(small, (n, n), interpolation=cv2.INTER_NEAREST if cells >= 64 else cv2.INTER_CUBIC), np.float32
        )
    acc = np.asarray(cv2.GaussianBlur(acc, (0, 0), 1.0), np.float32)
    acc = (acc - acc.min()) / (acc.max() - acc.min())
    return (30 + 200 * acc).astype(np.uint8)


@dataclass
class TexturedRoom:
    """An axis-aligned box room seen from inside."""

    half_x: float = 4.0
    half_y: float = 3.0
    height: float = 3.0
    texels_per_m: float = 200.0
    textureless: tuple[str, ...] = ()
    """Faces ('+x', '-x', '+y', '-y', 'floor', 'ceiling') painted flat grey."""
    seed: int = 0
    _tex: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        rng = np.random.default_rng(self.seed)
        n = 2048
        for face in _FACES:
            self._tex[face] = np.full((8, 8), 128, np.uint8) if face in self.textureless else _texture(rng, n)

    def render(self, R_WO: np.ndarray, p_WO: np.ndarray, cam: VioCamera) -> np.ndarray:
        """The grey (H, W) uint8 image of a pinhole camera at optical pose (R_WO, p_WO) (no distortion)."""
        w, h = cam.width, cam.height
        u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        d = np.stack([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, np.ones_like(u)], axis=-1) @ R_WO.T
        o = np.asarray(p_WO, dtype=float)
        lo = np.array([-self.half_x, -self.half_y, 0.0])
        hi = np.array([self.half_x, self.half_y, self.height])
        with np.errstate(divide="ignore", invalid="ignore"):
            tt = np.where(d > 0, (hi - o) / d, (lo - o) / d)
        tt = np.where(np.isfinite(tt) & (tt > 0), tt, np.inf)
        axis = np.argmin(tt, axis=-1)
        t = np.take_along_axis(tt, axis[..., None], -1)[..., 0]
        hit = o + d * t[..., None]
        positive = np.take_along_axis(d, axis[..., None], -1)[..., 0] > 0
        out = np.zeros((h, w), np.uint8)
        names = {
            (0, True): "+x",
            (0, False): "-x",
            (1, True): "+y",
            (1, False): "-y",
            (2, False): "floor",
            (2, True): "ceiling",
        }
        for (ax, pos), face in names.items():
            m = (axis == ax) & (positive == pos)
            if not m.any():
                continue
            a, b = [(1, 2), (0, 2), (0, 1)][ax]
            tex = self._tex[face]
            n = tex.shape[0]
            scale = self.texels_per_m * (n / 2048)
            mx = ((hit[..., a] - lo[a]) * scale).astype(np.float32)
            my = ((hit[..., b] - lo[b]) * scale).astype(np.float32)
            img = cv2.remap(tex, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
            out[m] = img[m]
        return out


def rotation_zyx(yaw: float, pitch: float, roll: float) -> np.ndarray:
    cy, sy, cp, sp, cr, sr = (
        math.cos(yaw),
        math.sin(yaw),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(roll),
        math.sin(roll),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


@dataclass
class Trajectory:
    """A body trajectory: ``pose(t) -> (R_WB, p_WB)``, smooth (finite differences give its derivatives)."""

    pose: Callable[[float], tuple[np.ndarray, np.ndarray]]

    def derivatives(self, t: float, h: float = 1e-4) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(R_WB, p_W, a_W, w_B) at t."""
        R, p = self.pose(t)
        Rm, pm = self.pose(t - h)
        Rp, pp = self.pose(t + h)
        a = (pp - 2 * p + pm) / (h * h)
        dR = (Rp - Rm) / (2 * h)
        W = R.T @ dR
        return R, p, a, np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]]) / 2


def _ramp(t: float, t0: float, t1: float) -> float:
    """0 before t0, 1 after t1, C2-smooth in between."""
    s = min(max((t - t0) / (t1 - t0), 0.0), 1.0)
    return s * s * s * (10 - 15 * s + 6 * s * s)


@dataclass
class SyntheticRun:
    imu: list[tuple[float, np.ndarray, np.ndarray]]
    """(t, f_I, w_I) at the IMU rate."""
    frames: list[tuple[float, np.ndarray, np.ndarray]]
    """(t, left, right) grey images."""
    truth_t: np.ndarray
    truth_p: np.ndarray
    """(N, 3) body positions at truth_t."""
    truth_q: np.ndarray
    """(N, 4) body attitudes [w, x, y, z]."""


def synthesize(
    trajectory: Trajectory,
    duration: float,
    cam0: VioCamera,
    cam1: VioCamera,
    room: TexturedRoom,
    imu_hz: float = 200.0,
    cam_hz: float = 20.0,
    gravity: float = 9.80665,
    accel_noise: float = 0.0,
    gyro_noise: float = 0.0,
    accel_bias: tuple[float, float, float] = (0.0, 0.0, 0.0),
    gyro_bias: tuple[float, float, float] = (0.0, 0.0, 0.0),
    seed: int = 0,
) -> SyntheticRun:
    """IMU samples (white noise densities ``*_noise`` [unit/sqrt(Hz)], constant biases) and stereo frames along
    ``trajectory`` (IMU frame = body frame), with the truth at the IMU rate."""
    rng = np.random.default_rng(seed)
    g = np.array([0.0, 0.0, -gravity])
    imu, ts, ps, qs = [], [], [], []
    n_imu = int(round(duration * imu_hz))
    for i in range(n_imu + 1):
        t = i / imu_hz
        R, p, a, w = trajectory.derivatives(t)
        f = R.T @ (a - g) + np.asarray(accel_bias) + rng.normal(0, accel_noise * math.sqrt(imu_hz), 3)
        wm = w + np.asarray(gyro_bias) + rng.normal(0, gyro_noise * math.sqrt(imu_hz), 3)
        imu.append((t, f, wm))
        ts.append(t)
        ps.append(p)
        qs.append(quat_from_matrix(R))
    frames = []
    T = []
    for cam in (cam0, cam1):
        M = homogeneous(cam.T_BC)
        M[:3, :3] = M[:3, :3] @ _R_CO
        T.append(M)
    for k in range(int(duration * cam_hz) + 1):
        t = k / cam_hz
        R, p = trajectory.pose(t)
        imgs = [room.render(R @ M[:3, :3], p + R @ M[:3, 3], cam) for M, cam in zip(T, (cam0, cam1), strict=True)]
        frames.append((t, imgs[0], imgs[1]))
    return SyntheticRun(imu, frames, np.array(ts), np.array(ps), np.array(qs))


def hover_then(
    motion: Callable[[float], tuple[float, float, float, float, float, float]],
    start: tuple[float, float, float],
    t_static: float = 1.5,
    t_ramp: float = 1.5,
) -> Trajectory:
    """Still at ``start`` (level, yaw 0) for ``t_static`` s, then ``motion(t')`` = (dx, dy, dz, yaw, pitch, roll)
    blended in over ``t_ramp`` s (t' counts from the end of the still part)."""
    p0 = np.asarray(start, dtype=float)

    def pose(t: float) -> tuple[np.ndarray, np.ndarray]:
        s = _ramp(t, t_static, t_static + t_ramp)
        dx, dy, dz, yaw, pitch, roll = motion(max(t - t_static, 0.0))
        return rotation_zyx(s * yaw, s * pitch, s * roll), p0 + s * np.array([dx, dy, dz])

    return Trajectory(pose)
