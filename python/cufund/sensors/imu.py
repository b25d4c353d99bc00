"""Inertial measurement unit: specific force and angular rate with the paper's error model (§2.2).

The IMU reads the true accelerations of the integrated dynamics (``Quadrotor.accel_W``/``alpha_B``, not
differences of states) at its mounting point: with lever arm ``p_BI`` (IMU position in body FLU) and
mounting rotation ``q_BI`` (IMU frame to body),

    f_B = R_WB^T (a_W + g e_z) + alpha_B x p_BI + w_B x (w_B x p_BI)     (specific force, body)
    f_I = R_BI^T f_B                                                       (true specific force, IMU frame)
    a_I = sat((I + diag(s_a) + C_a) f_I + vib_a(t) + b_a + n_a)
    w_I = sat((I + diag(s_g) + C_g) R_BI^T w_B + G f_I + vib_g(t) + b_g + n_g)

with ``s`` the scale-factor errors, ``C`` the cross-axis sensitivities (off-diagonal, zero diagonal), ``G`` the
gyroscope's g-sensitivity [rad/s per m/s^2], ``vib`` the rotor vibration after the anti-alias filter
(:mod:`cufund.sensors.imu_vibration`, from the true rotor speeds) and ``sat`` the per-axis full-scale range acting
on the total (vibration can clip), applied when ``saturation`` is on (off by default; the ``realistic`` profile
turns it on with the part's datasheet ranges, e.g. the BMI088's +-24 g / +-2000 deg/s). Every term but the noise
defaults to zero.

A level IMU at rest reads +g on its z axis (FLU). Noise densities use Kalibr's and PX4's units:
accelerometer m/s^2/sqrt(Hz) and random walk m/s^3/sqrt(Hz); gyroscope rad/s/sqrt(Hz) and rad/s^2/sqrt(Hz).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cufund.core.config import ConfigError, check_real_fields, from_dict, nested
from cufund.core.messages import Imu, Odometry, Topics
from cufund.geometry import quat_to_matrix, world_to_body

from .imu_vibration import RotorVibration, VibrationSpec
from .model_sensor import ModelSensor
from .noise import ErrorProcess, NoiseSpec, real_fields

__all__ = ["IMU_PRESETS", "ImuModel", "ImuParams", "ImuSensor", "VibrationSpec", "imu_preset"]

G0 = 9.80665
DEG = math.pi / 180.0


def _vec(name: str, value: object, dim: int) -> tuple[float, ...]:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        a = np.full(1, np.nan)  # reported below
    if a.shape != (dim,) or not np.all(np.isfinite(a)):
        raise ConfigError(f"{name} must be {dim} finite numbers, got {value!r}")
    return tuple(float(x) for x in a)


_CROSS_AXIS_INDEX = ((0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1))
"""Matrix positions of the cross-axis terms (xy, xz, yx, yz, zx, zy): row = output axis, column = input."""


def sensitivity_matrix(scale_factor: tuple[float, ...], cross_axis: tuple[float, ...]) -> np.ndarray:
    """I + diag(scale_factor) + C, with C's off-diagonal elements in the order (xy, xz, yx, yz, zx, zy)."""
    m = np.eye(3) + np.diag(scale_factor)
    for (i, j), c in zip(_CROSS_AXIS_INDEX, cross_axis, strict=True):
        m[i, j] = c
    return m


@dataclass(frozen=True)
class ImuParams:
    """An IMU part and its mounting. SI units; see the module docstring for the noise units."""

    rate_hz: float = 200.0
    """Output rate [Hz], 100-1000."""
    accel: NoiseSpec = field(default_factory=NoiseSpec)
    """Accelerometer errors [m/s^2/sqrt(Hz)], [m/s^3/sqrt(Hz)], turn-on bias [m/s^2]."""
    gyro: NoiseSpec = field(default_factory=NoiseSpec)
    """Gyroscope errors [rad/s/sqrt(Hz)], [rad/s^2/sqrt(Hz)], turn-on bias [rad/s]."""
    accel_scale_factor: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Scale-factor error per axis (0.01 reads 1 % high)."""
    gyro_scale_factor: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Scale-factor error per axis."""
    accel_range: float = 16 * G0
    """Full-scale range of each accelerometer axis [m/s^2] (the readings clip there when ``saturation`` is on)."""
    gyro_range: float = 2000 * DEG
    """Full-scale range of each gyroscope axis [rad/s] (the readings clip there when ``saturation`` is on)."""
    saturation: bool = False
    """Whether readings clip at the full-scale ranges (off: the model reads any motion, e.g. a hard landing's
    impact, unclipped)."""
    accel_cross_axis: tuple[float, float, float, float, float, float] = (0.0,) * 6
    """Cross-axis sensitivity, the off-diagonal elements (xy, xz, yx, yz, zx, zy) of the sensitivity matrix
    (0.01: 1 % of the y-axis input leaks into x for xy). Measured = (I + diag(scale_factor) + C) true."""
    gyro_cross_axis: tuple[float, float, float, float, float, float] = (0.0,) * 6
    """Gyroscope cross-axis sensitivity, as ``accel_cross_axis``."""
    gyro_g_sensitivity: tuple[float, ...] = (0.0,) * 9
    """Gyroscope sensitivity to specific force, 3x3 row-major [rad/s per m/s^2] (times the true f_I)."""
    vibration: VibrationSpec = field(default_factory=VibrationSpec)
    """Rotor vibration through the anti-alias filter (default: none)."""
    p_BI: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """IMU position in the body frame (lever arm from the centre of mass) [m]."""
    q_BI: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
    """IMU frame to body frame rotation [w, x, y, z]."""
    name: str = "ideal"

    def __post_init__(self) -> None:
        real_fields(self, "ImuParams")
        if not (math.isfinite(self.rate_hz) and 100.0 <= self.rate_hz <= 1000.0):
            raise ConfigError(f"rate_hz must be between 100 and 1000 [Hz], got {self.rate_hz!r}")
        for f in ("accel", "gyro"):
            object.__setattr__(self, f, nested(NoiseSpec, getattr(self, f), f"ImuParams.{f}"))
            getattr(self, f).per_axis(3)  # validates
        for f in ("accel_scale_factor", "gyro_scale_factor", "p_BI"):
            object.__setattr__(self, f, _vec(f, getattr(self, f), 3))
        for f, dim in (("accel_cross_axis", 6), ("gyro_cross_axis", 6), ("gyro_g_sensitivity", 9)):
            object.__setattr__(self, f, _vec(f"ImuParams.{f}", getattr(self, f), dim))
        object.__setattr__(self, "vibration", nested(VibrationSpec, self.vibration, "ImuParams.vibration"))
        object.__setattr__(self, "q_BI", _vec("q_BI", self.q_BI, 4))
        q = np.asarray(self.q_BI)
        if abs(np.linalg.norm(q) - 1.0) > 1e-6:
            raise ConfigError(f"q_BI must be a unit quaternion [w, x, y, z], got norm {np.linalg.norm(q)}")
        check_real_fields(self, "ImuParams", positive=True, names=("accel_range", "gyro_range"))
        if not isinstance(self.saturation, bool):
            raise ConfigError(f"ImuParams.saturation must be true or false, got {self.saturation!r}")

    @classmethod
    def from_dict(cls, data: dict) -> ImuParams:
        return from_dict(cls, data, "ImuParams")


class ImuModel:
    """Turns true motion into IMU samples, one at a time or as a whole record, from one seeded stream."""

    def __init__(self, params: ImuParams, seed: int = 0, gravity: float = G0) -> None:
        self.params = params
        self.gravity = float(gravity)
        self._errors = ErrorProcess([(params.accel, 3), (params.gyro, 3)], 1.0 / params.rate_hz, seed)
        self._R_IB = quat_to_matrix(np.asarray(params.q_BI)).T
        self._r = np.asarray(params.p_BI)
        self._r_tuple = tuple(float(v) for v in params.p_BI)
        self._M_a = sensitivity_matrix(params.accel_scale_factor, params.accel_cross_axis)
        self._M_g = sensitivity_matrix(params.gyro_scale_factor, params.gyro_cross_axis)
        self._G = np.asarray(params.gyro_g_sensitivity).reshape(3, 3) if any(params.gyro_g_sensitivity) else None
        self._vibration = (
            RotorVibration(params.vibration, 1.0 / params.rate_hz, seed) if params.vibration.enabled else None
        )
        self._sat = params.saturation
        self._mounted = (  # anything but white noise, bias and saturation: the general (matrix) path
            tuple(params.q_BI) != (1.0, 0.0, 0.0, 0.0)
            or any(params.accel_scale_factor)
            or any(params.gyro_scale_factor)
            or any(params.accel_cross_axis)
            or any(params.gyro_cross_axis)
            or self._G is not None
            or self._vibration is not None
        )

    def reset(self) -> None:
        """Restarts the error stream and the rotors' angles (same seed: the same record again)."""
        self._errors.reset()
        if self._vibration is not None:
            self._vibration.reset()

    @property
    def vibrates(self) -> bool:
        """Whether the model has rotor vibration (then it reads the true rotor speeds)."""
        return self._vibration is not None

    @property
    def bias(self) -> tuple[np.ndarray, np.ndarray]:
        """Current total accelerometer and gyroscope biases [m/s^2], [rad/s] (turn-on + random walk)."""
        b = self._errors.turn_on_bias + self._errors.bias
        return b[:3].copy(), b[3:].copy()

    def measure(
        self,
        q_WB: np.ndarray,
        w_B: np.ndarray,
        a_W: np.ndarray,
        alpha_B: np.ndarray,
        rotor_speeds: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Samples for the true attitude q_WB (K, 4) [w, x, y, z], body rate w_B (K, 3) [rad/s], acceleration
        a_W (K, 3) [m/s^2] and angular acceleration alpha_B (K, 3) [rad/s^2]; or one sample from (4,)/(3,).
        ``rotor_speeds`` (K, n) or (n,) [rad/s], the true rotor speeds, drive the vibration (None: rotors
        stopped; ignored without vibration). Consecutive samples are one output period apart.
        Returns (accelerometer (K, 3) [m/s^2], gyroscope (K, 3) [rad/s]) in the IMU frame."""
        rotors = None
        if self._vibration is not None and rotor_speeds is not None:
            rotors = np.asarray(rotor_speeds, dtype=float)
            if rotors.ndim not in (1, 2) or rotors.shape[-1] < 1 or not np.all(np.isfinite(rotors)):
                raise ValueError(f"rotor_speeds must be finite, shape (n,) or (K, n), got shape {rotors.shape}")
        if (
            type(q_WB) is np.ndarray
            and q_WB.shape == (4,)
            and type(w_B) is np.ndarray
            and w_B.shape == (3,)
            and type(a_W) is np.ndarray
            and a_W.shape == (3,)
            and type(alpha_B) is np.ndarray
            and alpha_B.shape == (3,)
        ):
            # the tick path
            return self._measure_one(q_WB.tolist(), w_B.tolist(), a_W.tolist(), alpha_B.tolist(), rotors)
        single = np.ndim(q_WB) == 1
        if single and np.shape(w_B) == (3,) and np.shape(a_W) == (3,) and np.shape(alpha_B) == (3,):
            return self._measure_one(
                [float(v) for v in q_WB],
                [float(v) for v in w_B],
                [float(v) for v in a_W],
                [float(v) for v in alpha_B],
                rotors,
            )
        q, w, a, al = (np.atleast_2d(np.asarray(x, dtype=float)) for x in (q_WB, w_B, a_W, alpha_B))
        k = q.shape[0]
        for name, x, d in (("q_WB", q, 4), ("w_B", w, 3), ("a_W", a, 3), ("alpha_B", al, 3)):
            if x.shape != (k, d):
                raise ValueError(f"{name} must have shape ({k}, {d}), got {x.shape}")
            if not np.all(np.isfinite(x)):
                raise ValueError(f"{name} must be finite")
        R_WB = quat_to_matrix(q)
        f_B = np.einsum("kji,kj->ki", R_WB, a + np.array([0.0, 0.0, self.gravity]))
        f_B += np.cross(al, self._r) + np.cross(w, np.cross(w, self._r))
        if rotors is not None and rotors.shape[:-1] != (k,):
            raise ValueError(f"rotor_speeds must have shape ({k}, n), got {rotors.shape}")
        e = self._errors.sample(k)
        f_I = f_B @ self._R_IB.T
        acc = f_I @ self._M_a.T + e[:, :3]
        gyr = (w @ self._R_IB.T) @ self._M_g.T + e[:, 3:]
        if self._G is not None:
            gyr += f_I @ self._G.T
        if self._vibration is not None:
            va, vg = self._vibration.sample(rotors, k)
            acc += va
            gyr += vg
        if self._sat:
            acc = np.clip(acc, -self.params.accel_range, self.params.accel_range)
            gyr = np.clip(gyr, -self.params.gyro_range, self.params.gyro_range)
        return (acc[0], gyr[0]) if single else (acc, gyr)

    def _measure_one(
        self, q: list[float], w: list[float], a: list[float], alpha: list[float], rotors: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """One sample with scalar arithmetic on Python floats (the simulator's per-tick path: the same model as
        the batch path, equal to it within rounding). ``q`` [w, x, y, z], ``w``, ``a``, ``alpha``: 3 floats;
        ``rotors`` the rotor speeds (n,) (used by the vibration only)."""
        qw, qx, qy, qz = q
        wx, wy, wz = w
        ax, ay, az = a
        bx, by, bz = alpha
        # one finiteness test for all 13 inputs (a sum of finite numbers may still overflow: then look closer)
        if not math.isfinite(qw + qx + qy + qz + wx + wy + wz + ax + ay + az + bx + by + bz):
            for name, values in (("q_WB", q), ("w_B", w), ("a_W", a), ("alpha_B", alpha)):
                if not all(math.isfinite(v) for v in values):
                    raise ValueError(f"{name} must be finite")
        az += self.gravity
        fx, fy, fz = world_to_body(qw, qx, qy, qz, ax, ay, az)  # f_B = R_WB^T (a_W + g e_z)
        rx, ry, rz = self._r_tuple
        if rx or ry or rz:
            cx, cy, cz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx  # w x r
            fx += by * rz - bz * ry + wy * cz - wz * cy
            fy += bz * rx - bx * rz + wz * cx - wx * cz
            fz += bx * ry - by * rx + wx * cy - wy * cx
        if self._mounted:
            if rotors is not None and rotors.ndim != 1:
                raise ValueError(f"rotor_speeds must have shape (n,) for one sample, got {rotors.shape}")
            e = self._errors.sample_one()
            f_I = self._R_IB @ np.array((fx, fy, fz))
            f = self._M_a @ f_I + e[:3]
            g = self._M_g @ (self._R_IB @ np.array((wx, wy, wz))) + e[3:]
            if self._G is not None:
                g += self._G @ f_I
            if self._vibration is not None:
                va, vg = self._vibration.sample_one(rotors)
                f += va
                g += vg
            if self._sat:
                ar, gr = self.params.accel_range, self.params.gyro_range
                if max(abs(f[0]), abs(f[1]), abs(f[2])) > ar:
                    f = np.clip(f, -ar, ar)
                if max(abs(g[0]), abs(g[1]), abs(g[2])) > gr:
                    g = np.clip(g, -gr, gr)
            return f, g
        # IMU axes along the body's, no scale-factor error: no matrix products, no arrays until the result
        e0, e1, e2, e3, e4, e5 = self._errors.sample_one_values()
        fx, fy, fz, wx, wy, wz = fx + e0, fy + e1, fz + e2, wx + e3, wy + e4, wz + e5
        if self._sat:
            ar, gr = self.params.accel_range, self.params.gyro_range
            if max(abs(fx), abs(fy), abs(fz)) > ar:
                fx, fy, fz = (min(max(v, -ar), ar) for v in (fx, fy, fz))
            if max(abs(wx), abs(wy), abs(wz)) > gr:
                wx, wy, wz = (min(max(v, -gr), gr) for v in (wx, wy, wz))
        return np.array((fx, fy, fz)), np.array((wx, wy, wz))

    def measure_static(
        self, k: int, q_WB: np.ndarray | tuple[float, ...] = (1.0, 0.0, 0.0, 0.0)
    ) -> tuple[np.ndarray, np.ndarray]:
        """``k`` samples of an IMU at rest with attitude ``q_WB`` (level by default)."""
        q = np.broadcast_to(np.asarray(q_WB, dtype=float), (k, 4))
        z = np.zeros((k, 3))
        return self.measure(q, z, z, z)


class ImuSensor(ModelSensor):
    """Publishes :class:`~cufund.core.messages.Imu` samples (in the IMU frame, ``f_I`` and ``w_I``) at the part's
    rate from ground truth's true accelerations. ``gravity`` must be the vehicle's (``params.gravity``)."""

    name = "imu"

    def __init__(self, params: ImuParams, seed: int = 0, gravity: float = G0, topic: str = Topics.IMU) -> None:
        super().__init__(ImuModel(params, seed, gravity), params.rate_hz, topic)

    def measure(self, t: float, truth: Odometry) -> Imu:
        if truth.a_W is None or truth.alpha_B is None:
            raise ValueError(
                "ImuSensor needs ground truth with accelerations (a_W, alpha_B), as the Simulator publishes"
            )
        if self.model.vibrates:
            a, w = self.model.measure(truth.q_WB, truth.w_B, truth.a_W, truth.alpha_B, truth.rotor_speeds)
        else:
            a, w = self.model.measure(truth.q_WB, truth.w_B, truth.a_W, truth.alpha_B)
        a.setflags(write=False)  # fresh arrays the model keeps no reference to: frozen, the message is trusted
        w.setflags(write=False)
        return Imu.trusted(t, a, w)


def _mems(
    name: str,
    rate_hz: float,
    acc_nd_ug: float,
    gyro_nd_dps: float,
    acc_rw: float,
    gyro_rw: float,
    acc_range_g: float,
    gyro_range_dps: float,
    acc_bias_mg: float,
    gyro_bias_dps: float,
) -> ImuParams:
    return ImuParams(
        name=name,
        rate_hz=rate_hz,
        accel=NoiseSpec(acc_nd_ug * 1e-6 * G0, acc_rw, acc_bias_mg * 1e-3 * G0),
        gyro=NoiseSpec(gyro_nd_dps * DEG, gyro_rw, gyro_bias_dps * DEG),
        accel_range=acc_range_g * G0,
        gyro_range=gyro_range_dps * DEG,
    )


#: Presets, at 200 Hz (an output data rate both parts offer, dividing the 1 kHz physics rate).
#: White-noise densities, ranges and zero-offsets are the datasheets' typical values:
#: Bosch BMI088 (BST-BMI088-DS001): accelerometer 175 ug/sqrt(Hz) (the datasheet's 160-190 by axis),
#: +-24 g, offset 20 mg; gyroscope 0.014 deg/s/sqrt(Hz), +-2000 deg/s, offset 1 deg/s.
#: TDK ICM-42688-P (DS-000347): accelerometer 70 ug/sqrt(Hz), +-16 g, offset +-20 mg; gyroscope
#: 0.0028 deg/s/sqrt(Hz), +-2000 deg/s, offset +-0.5 deg/s.
#: Datasheets do not give bias random walks; the values used (accelerometer 4e-4 m/s^3/sqrt(Hz),
#: gyroscope 2e-5 rad/s^2/sqrt(Hz) for BMI088, half that for ICM-42688-P) are of the order that
#: Allan-variance calibrations of these parts report and that PX4/Kalibr examples use; change them to
#: your own Allan-fit numbers (``cufund allan`` shows how they appear).
IMU_PRESETS = {
    "bmi088": lambda: _mems("bmi088", 200.0, 175.0, 0.014, 4e-4, 2e-5, 24.0, 2000.0, 20.0, 1.0),
    "icm42688p": lambda: _mems("icm42688p", 200.0, 70.0, 0.0028, 2e-4, 1e-5, 16.0, 2000.0, 20.0, 0.5),
    "ideal": lambda: ImuParams(name="ideal"),
}


def imu_preset(name: str) -> ImuParams:
    """An IMU preset by name: ``bmi088``, ``icm42688p`` or ``ideal``."""
    try:
        return IMU_PRESETS[name]()
    except KeyError:
        raise ConfigError(f"unknown IMU preset {name!r}; expected one of: {', '.join(IMU_PRESETS)}") from None
