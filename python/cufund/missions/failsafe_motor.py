"""Motor failure detection from flight data only: the rate residuals and the attitude.

**Rate residual.** A generalised-momentum observer (De Luca & Mattone, ICRA 2003, applied to multirotors e.g. by
Tomić & Haddadin, IROS 2014) on the rigid body's rotation::

    r(t) = K (J w(t) - J w(t0) - integral_{t0}^{t} (tau_cmd - w x J w + r) ds)

follows the torque the model does not explain, low-passed at ``K`` [rad/s]: ``r' = K (tau_ext - r)``. ``w`` is the
measured body rate (the gyro, turned into the body frame by the IMU's stated mounting), ``J`` the nominal inertia,
and ``tau_cmd`` the torque the *commanded* rotor speeds produce through the nominal allocation, each rotor speed
lagged by the motor's nominal time constant ``tau_m``. A rotor that stops (or loses efficiency ``eta``) removes
``(1 - eta) T_i (r_i x e_z)`` of roll/pitch torque that the command still claims, so ``r`` settles at minus that:
the detector fires when ``|r_xy|`` exceeds ``threshold`` times one rotor's hover torque ``(m g / 4) l`` for
``t_trigger`` seconds, and names the rotor whose lever ``-(r_i x e_z)`` is best aligned with ``r_xy``.
Nothing here reads ground truth.

**Attitude.** Roll or pitch of the estimate beyond PX4's FD_FAIL_R / FD_FAIL_P for FD_FAIL_R_TTRI /
FD_FAIL_P_TTRI is an attitude failure (the supervisor disarms, as PX4's flight termination does).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cufund.geometry import euler_zyx

__all__ = ["AttitudeFailureDetector", "MotorFailureDetector"]


class MotorFailureDetector:
    """Feed it :meth:`command` (commanded rotor speeds [rad/s], PX4 numbering) and :meth:`gyro` (body rates
    [rad/s] in the body frame, time-ordered); :attr:`failed` and :attr:`motor` (0-based) once it fired.
    ``vehicle`` is the nominal :class:`~cufund.vehicle.params.QuadrotorParams` flight software is told."""

    def __init__(self, vehicle: Any, threshold: float = 0.5, t_trigger: float = 0.15, bandwidth: float = 15.0) -> None:
        self.J = np.asarray(vehicle.inertia_matrix, dtype=float)
        self.A = np.asarray(vehicle.allocation_matrix(), dtype=float)  # rotor thrusts -> [f, Mx, My, Mz]
        self.k_f = float(vehicle.k_f)
        self.tau_m = float(vehicle.tau_m)
        self.levers = np.asarray(self.A[1:3, :].T, dtype=float)  # (4, 2): roll/pitch torque per newton of rotor i
        hover = vehicle.mass * vehicle.gravity / 4.0
        self.torque_scale = hover * float(np.max(np.linalg.norm(self.levers, axis=1)))
        """One rotor's hover thrust times its roll/pitch lever [N m]: the residual's unit."""
        self.threshold, self.t_trigger, self.K = float(threshold), float(t_trigger), float(bandwidth)
        self._Jrows = [[float(v) for v in row] for row in self.J]
        self._Arows = [[float(v) for v in row] for row in self.A[1:, :]]
        self.min_dt = 1.0 / 100.0 - 1e-9
        """Samples closer than this to the last one taken are skipped (see :meth:`due`) [s]."""
        self.reset()

    def reset(self) -> None:
        """Starts over (e.g. when the vehicle leaves the ground: contact torques are no failure)."""
        self.failed = False
        self.motor: int | None = None
        self.t_failed: float | None = None
        self.residual = [0.0, 0.0, 0.0]
        """The observer's output: the unexplained body torque [N m], (3,)."""
        self.peak = 0.0
        """The largest |r_xy| / torque_scale seen since the reset [-]."""
        self._speeds: list[float] | None = None  # the modelled (lagged) rotor speeds [rad/s]
        self._cmd: list[float] | None = None
        self._t: float | None = None
        self._p0: list[float] | None = None  # J w at the start
        self._integral = [0.0, 0.0, 0.0]
        self._w = [0.0, 0.0, 0.0]
        self._Jw = [0.0, 0.0, 0.0]  # J w of the last sample
        self._since: float | None = None

    def command(self, t: float, rotor_speeds: Any) -> None:
        """The newest commanded rotor speeds (held until the next command)."""
        self._cmd = rotor_speeds.tolist() if isinstance(rotor_speeds, np.ndarray) else [float(v) for v in rotor_speeds]
        if len(self._cmd) != 4:
            raise ValueError(f"rotor_speeds must be 4 speeds [rad/s], got {len(self._cmd)}")
        if self._speeds is None:
            self._speeds = list(self._cmd)

    def torque(self) -> np.ndarray:
        """The body torque [N m] of the modelled rotor speeds through the nominal allocation."""
        assert self._speeds is not None
        return self.A[1:, :] @ (self.k_f * np.asarray(self._speeds) ** 2)

    def due(self, t: float) -> bool:
        """Whether a sample at ``t`` is worth taking: at most 100 Hz (the observer low-passes at ``K`` rad/s, far
        below; faster gyros are decimated)."""
        return self._t is None or float(t) - self._t >= self.min_dt

    def _J(self, w: list[float]) -> list[float]:
        J = self._Jrows
        return [
            J[0][0] * w[0] + J[0][1] * w[1] + J[0][2] * w[2],
            J[1][0] * w[0] + J[1][1] * w[1] + J[1][2] * w[2],
            J[2][0] * w[0] + J[2][1] * w[1] + J[2][2] * w[2],
        ]

    def gyro(self, t: float, w_B: Any) -> None:
        """One gyro sample (body frame): advances the rotor model and the observer to ``t`` (plain floats: it
        runs at up to 100 Hz in the loop)."""
        if self._cmd is None:
            return
        assert self._speeds is not None
        t = float(t)
        w = w_B.tolist() if isinstance(w_B, np.ndarray) else [float(w_B[0]), float(w_B[1]), float(w_B[2])]
        Jw = self._J(w)
        if self._t is None or self._p0 is None:
            self._t, self._p0, self._w, self._Jw = t, Jw, w, Jw
            return
        dt = t - self._t
        if dt <= 0:
            return
        kf, sp, A = self.k_f, self._speeds, self._Arows
        f0, f1, f2, f3 = kf * sp[0] * sp[0], kf * sp[1] * sp[1], kf * sp[2] * sp[2], kf * sp[3] * sp[3]
        tau = [row[0] * f0 + row[1] * f1 + row[2] * f2 + row[3] * f3 for row in A]
        wp, Jwp = self._w, self._Jw  # the integrand at the previous sample
        gyro_torque = [
            wp[1] * Jwp[2] - wp[2] * Jwp[1],
            wp[2] * Jwp[0] - wp[0] * Jwp[2],
            wp[0] * Jwp[1] - wp[1] * Jwp[0],
        ]
        r, acc, p0 = self.residual, self._integral, self._p0
        for k in range(3):  # the integrand at the previous sample (explicit Euler)
            acc[k] += (tau[k] - gyro_torque[k] + r[k]) * dt
        self.residual = r = [self.K * (Jw[k] - p0[k] - acc[k]) for k in range(3)]
        lag = 1.0 - math.exp(-dt / self.tau_m)
        cmd = self._cmd
        for k in range(4):
            sp[k] += (cmd[k] - sp[k]) * lag
        self._t, self._w, self._Jw = t, w, Jw
        level = math.hypot(r[0], r[1]) / self.torque_scale
        if level > self.peak:
            self.peak = level
        if self.failed:
            return
        if level > self.threshold:
            if self._since is None:
                self._since = t
            if t - self._since >= self.t_trigger:
                self.failed, self.t_failed = True, t
                # the lost torque is -(eta loss) T_i lever_i: the rotor whose lever best opposes the residual
                rxy = np.array(r[:2]) / math.hypot(r[0], r[1])
                cos = -(self.levers @ rxy) / np.linalg.norm(self.levers, axis=1)
                self.motor = int(np.argmax(cos))
        else:
            self._since = None


class AttitudeFailureDetector:
    """PX4's failure detector on attitude: roll beyond ``max_roll_deg`` for ``roll_s``, or pitch beyond
    ``max_pitch_deg`` for ``pitch_s`` (0 degrees: that axis is off)."""

    def __init__(self, max_roll_deg: float, max_pitch_deg: float, roll_s: float, pitch_s: float) -> None:
        self.max_roll, self.max_pitch = math.radians(max_roll_deg), math.radians(max_pitch_deg)
        self.roll_s, self.pitch_s = float(roll_s), float(pitch_s)
        self.reset()

    def reset(self) -> None:
        self.failed = False
        self.reason = ""
        self._roll_since: float | None = None
        self._pitch_since: float | None = None

    def update(self, t: float, q_WB: Any) -> bool:
        if self.failed:
            return True
        roll, pitch, _ = euler_zyx(q_WB)
        # upside down: roll reads ~180 deg and pitch small, so the tilt from level counts for both
        w, x, y, z = (float(v) for v in q_WB)
        tilt = math.acos(max(-1.0, min(1.0, 1 - 2 * (x * x + y * y))))
        for axis, angle, limit, hold, since in (
            (
                "roll",
                max(abs(roll), tilt if abs(roll) > math.pi / 2 else 0.0),
                self.max_roll,
                self.roll_s,
                "_roll_since",
            ),
            ("pitch", abs(pitch), self.max_pitch, self.pitch_s, "_pitch_since"),
        ):
            if limit > 0 and angle > limit:
                t0 = getattr(self, since)
                if t0 is None:
                    setattr(self, since, t)
                elif t - t0 >= hold:
                    self.failed = True
                    self.reason = (
                        f"{axis} {math.degrees(angle):.0f} deg beyond {math.degrees(limit):.0f} deg for {t - t0:.2f} s"
                    )
                    return True
            else:
                setattr(self, since, None)
        return False
