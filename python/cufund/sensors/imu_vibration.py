"""Rotor vibration as an IMU sees it: imbalance lines at the rotor rate and its harmonics, through the part's
anti-alias filter, sampled at the output rate (aliasing comes out of the sampling itself).

Rotor ``i`` turning at ``w_i`` [rad/s] (the true rotor speed times a fixed seeded imbalance factor
``1 + speed_spread * N(0, 1)``: the line of a real rotor is not exactly at its commanded speed) shakes the IMU,
for each harmonic ``k`` (ratio ``h_k``) and axis ``j``, with

    v_j(t) = sum_i sum_k  A_j h_k (w_i / w_hover)^2 / 4 * |H(f_ik)| * sin(k theta_i(t) + phi_ikj + arg H(f_ik))

where ``f_ik = k w_i / (2 pi)`` [Hz], ``theta_i`` the rotor's angle (integrated sample to sample with the
trapezoidal rule, ``theta += (w_prev + w) / 2 * dt``, so a speed ramp is a chirp, not a phase jump), ``phi`` a
fixed seeded phase per rotor, harmonic, axis and sensor, and ``H`` the order-n analog Butterworth low-pass of
the part's anti-alias filter at ``anti_alias_hz``. ``A`` is the amplitude of the rotor-rate line at hover (all
four rotors in phase); amplitude grows with the square of the rotor speed (imbalance force ~ w^2) and is zero
with the rotors stopped.

The realistic amplitudes are the ``realism`` profile's (docs/realism.md, with their sources); with every
amplitude zero (the default) the model is off. The default filter corner, 80 Hz, is the BMI088 accelerometer's
normal-mode bandwidth at a 200 Hz output rate (BST-BMI088-DS001, register ACC_CONF). Note that ``A`` is the
line with all rotors in phase: with the seeded phases of four equal-speed rotors the line's amplitude is
``A |sum_i exp(j phi_i)| / 4`` (A / 2 in the RMS over phases), and with ``speed_spread`` the rotors' lines
beat.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cufund.core.config import ConfigError, check_at_most, check_real_fields, from_dict

__all__ = ["RotorVibration", "VibrationSpec", "butterworth_poles", "butterworth_response"]

MAX_ROTORS = 8
"""Rotors the seeded phases are drawn for (a quadrotor uses the first four, in PX4's numbering)."""


def _tuple(where: str, value: object, dim: int | None) -> tuple[float, ...]:
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        a = np.full((), np.nan)  # reported below
    ok = a.ndim == 1 and (a.shape[0] == dim if dim is not None else a.shape[0] >= 1)
    if not ok or not np.all(np.isfinite(a)) or np.any(a < 0):
        what = f"{dim} finite numbers >= 0" if dim is not None else "a list of finite numbers >= 0 (at least one)"
        raise ConfigError(f"{where} must be {what}, got {value!r}")
    return tuple(float(x) for x in a)


@dataclass(frozen=True)
class VibrationSpec:
    """Rotor vibration reaching an IMU (default: none). SI units."""

    accel_mps2: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Amplitude of the accelerometer's rotor-rate line at hover rotor speed, per IMU axis [m/s^2]."""
    gyro_radps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Amplitude of the gyroscope's rotor-rate line at hover rotor speed, per IMU axis [rad/s]."""
    harmonics: tuple[float, ...] = (1.0,)
    """Amplitude ratios of the lines at 1x, 2x, 3x ... the rotor rate."""
    speed_spread: float = 0.0
    """Relative spread of each rotor's line frequency about its speed (a fixed seeded factor per rotor)."""
    hover_rotor_speed: float = 0.0
    """Rotor speed at hover [rad/s], where the amplitudes apply; must be > 0 when any amplitude is."""
    anti_alias_hz: float = 80.0
    """The IMU's anti-alias filter corner (-3 dB) [Hz]."""
    anti_alias_order: int = 2
    """Order of the anti-alias filter (Butterworth), 1-8."""

    def __post_init__(self) -> None:
        where = "ImuParams.vibration"
        for name in ("accel_mps2", "gyro_radps"):
            object.__setattr__(self, name, _tuple(f"{where}.{name}", getattr(self, name), 3))
        object.__setattr__(self, "harmonics", _tuple(f"{where}.harmonics", self.harmonics, None))
        check_real_fields(self, where, names=("speed_spread", "hover_rotor_speed"))
        check_real_fields(self, where, positive=True, unit=" [Hz]", names=("anti_alias_hz",))
        check_at_most(self, where, anti_alias_hz=1e5)  # a MEMS part's filter corners stay in the kHz
        n = self.anti_alias_order
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 8:
            raise ConfigError(f"{where}.anti_alias_order must be an integer from 1 to 8, got {n!r}")
        object.__setattr__(self, "anti_alias_order", int(n))
        if self.enabled and self.hover_rotor_speed <= 0:
            raise ConfigError(
                f"{where}.hover_rotor_speed must be > 0 [rad/s] when an amplitude is set, got {self.hover_rotor_speed!r}"
            )

    @property
    def enabled(self) -> bool:
        """Whether any line has a non-zero amplitude."""
        return any(self.accel_mps2) or any(self.gyro_radps)

    @classmethod
    def from_dict(cls, data: dict) -> VibrationSpec:
        return from_dict(cls, data, "ImuParams.vibration")


def butterworth_poles(order: int) -> np.ndarray:
    """The normalised analog Butterworth poles p_k = exp(j pi (2k + n - 1) / (2n)), k = 1..n (the left half of
    the unit circle)."""
    k = np.arange(1, order + 1)
    return np.exp(1j * np.pi * (2 * k + order - 1) / (2 * order))


def butterworth_response(f_hz: np.ndarray, corner_hz: float, order: int, poles: np.ndarray | None = None) -> np.ndarray:
    """Complex frequency response H(j 2 pi f) of the order-``order`` analog Butterworth low-pass with its -3 dB
    corner at ``corner_hz``: 1 / prod_k (j f / f_c - p_k) (unit gain at DC); ``poles``: the
    :func:`butterworth_poles` of ``order``, when the caller keeps them."""
    p = butterworth_poles(order) if poles is None else poles
    s = 1j * np.asarray(f_hz, dtype=float)[..., None] / corner_hz
    return 1.0 / np.prod(s - p, axis=-1)


class RotorVibration:
    """The vibration of :class:`VibrationSpec` sampled every ``dt`` seconds, as a stream: each call continues the
    rotors' angles from the last sample. The seeded parts (speed factors, phases) are fixed for the model's life;
    :meth:`reset` restarts the angles (same seed, same inputs: the same record)."""

    def __init__(self, spec: VibrationSpec, dt: float, seed: int) -> None:
        self.spec = spec
        self.dt = float(dt)
        rng = np.random.default_rng([abs(int(seed)), 0x1B4A])  # its own stream: the noise's is left as it was
        self.speed_factor = 1.0 + spec.speed_spread * rng.standard_normal(MAX_ROTORS)
        h = len(spec.harmonics)
        phases = rng.uniform(0.0, 2.0 * np.pi, (2, h, MAX_ROTORS, 3))  # [accel | gyro, harmonic, rotor, axis]
        # each line's unit phasor on the six outputs (accelerometer x, y, z, gyroscope x, y, z): (h, rotor, 6)
        self._phasors = np.concatenate([np.exp(1j * phases[0]), np.exp(1j * phases[1])], axis=-1)
        self._amp = np.concatenate([spec.accel_mps2, spec.gyro_radps])
        self._phasors_n: dict[int, np.ndarray] = {}  # (h n, 6) for n rotors
        self._order = np.arange(1, h + 1, dtype=float)  # k
        self._ratio = np.asarray(spec.harmonics) / 4.0  # h_k / 4 (four rotors in phase give A)
        self._inv_hover2 = 1.0 / spec.hover_rotor_speed**2 if spec.hover_rotor_speed > 0 else 0.0
        self._poles = butterworth_poles(spec.anti_alias_order)
        self.reset()

    def reset(self) -> None:
        """Rotor angles back to zero, no previous sample."""
        self._theta: np.ndarray | None = None  # angle of each rotor at the last sample [rad]
        self._w_last: np.ndarray | None = None  # its (imbalance) speed there [rad/s]

    def _speeds(self, rotor_speeds: np.ndarray | None, k: int) -> np.ndarray:
        """(k, n) line speeds [rad/s] from the true rotor speeds (k, n) (None: stopped)."""
        n = 4 if rotor_speeds is None else rotor_speeds.shape[1]
        if n > MAX_ROTORS:
            raise ValueError(f"rotor_speeds: at most {MAX_ROTORS} rotors, got {n}")
        if self._w_last is not None and self._w_last.shape[0] != n:
            raise ValueError(f"rotor_speeds: {n} rotors after {self._w_last.shape[0]} in the previous samples")
        if rotor_speeds is None:
            return np.zeros((k, n))
        return np.abs(rotor_speeds) * self.speed_factor[:n]

    def sample(self, rotor_speeds: np.ndarray | None, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Vibration of the next ``k`` samples given the true rotor speeds (k, n) [rad/s] at each (None: rotors
        stopped): (accelerometer (k, 3) [m/s^2], gyroscope (k, 3) [rad/s]) in the IMU frame."""
        w = self._speeds(rotor_speeds, k)
        n = w.shape[1]
        # rotor angles: trapezoidal integration from the last sample (the first sample after reset is at angle 0)
        prev = np.vstack([w[:1] if self._w_last is None else self._w_last[None, :], w[:-1]])
        steps = 0.5 * (prev + w) * self.dt
        if self._theta is None:
            steps[0] = 0.0
        start = np.zeros(n) if self._theta is None else self._theta
        theta = np.cumsum(np.vstack([start[None, :], steps]), axis=0)[1:]
        self._theta, self._w_last = theta[-1].copy(), w[-1].copy()
        if not np.any(w):
            z = np.zeros((k, 3))
            return z, z.copy()
        return self._lines(w, theta)

    def sample_one(self, rotor_speeds: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`sample` of one sample from the rotor speeds (n,): (accelerometer (3,), gyroscope (3,)); the
        same arithmetic, without the batch's stacking."""
        w = self._speeds(None if rotor_speeds is None else rotor_speeds[None, :], 1)[0]
        theta = np.zeros(len(w)) if self._theta is None else self._theta + 0.5 * (self._w_last + w) * self.dt
        self._theta, self._w_last = theta, w
        if not w.any():
            return np.zeros(3), np.zeros(3)
        a, g = self._lines(w[None, :], theta[None, :])
        return a[0], g[0]

    def _lines(self, w: np.ndarray, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The sum of every rotor's lines at speeds w (k, n) and angles theta (k, n)."""
        n = w.shape[1]
        # c[k, h, i]: complex amplitude of rotor i's harmonic h (phase k theta + arg H), before the axis phases
        order = self._order[None, :, None]
        freq = order * w[:, None, :] / (2.0 * np.pi)
        resp = butterworth_response(freq, self.spec.anti_alias_hz, self.spec.anti_alias_order, self._poles)
        c = (self._ratio[None, :, None] * (w * w * self._inv_hover2)[:, None, :]) * resp
        c = c * np.exp(1j * order * theta[:, None, :])
        phasors = self._phasors_n.get(n)
        if phasors is None:
            phasors = self._phasors_n[n] = self._phasors[:, :n].reshape(-1, 6)
        out = (c.reshape(len(w), -1) @ phasors).imag * self._amp
        return out[:, :3], out[:, 3:]
