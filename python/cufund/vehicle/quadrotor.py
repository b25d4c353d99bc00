"""Quadrotor rigid-body simulation, one vehicle or a batch (paper §2.1, eqs. 1-5).

The integration runs in C++ (RK4 at ``params.max_integration_step``, 1 kHz by default). State arrays are
numpy views into the C++ buffers: reading them costs no copy, and writing them sets the state.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from cufund import _core
from cufund.core import limits

from .params import QuadrotorParams

__all__ = ["Quadrotor", "QuadrotorBatch", "QuadrotorState", "WindField"]

#: Wind: a constant world-frame velocity [m/s] (shape (3,) or (N, 3)), or a function
#: ``wind(t, p_W) -> (3,) or (N, 3)`` of time [s] and positions (N, 3) [m], evaluated at the start of
#: each step and held over it.
WindField = None | np.ndarray | Callable[[float, np.ndarray], np.ndarray]


class QuadrotorBatch:
    """``n`` quadrotors with the same parameters, stepped together on all cores with the GIL released.

    State (views, shape (n, k), writable): ``p`` position p_W [m], ``v`` velocity v_W [m/s], ``q`` attitude
    q_WB [w, x, y, z], ``w`` body rate w_B [rad/s], ``rotor_speeds`` [rad/s] (PX4 numbering). Inputs held
    over a step: ``wind_W`` [m/s], ``force_ext_W`` [N], ``torque_ext_B`` [N m]. Outputs of the last step:
    ``accel_W`` [m/s^2] and ``alpha_B`` [rad/s^2], the model's true accelerations (zero while resting on
    the ground), which inertial sensors read.
    """

    def __init__(self, params: QuadrotorParams, n: int, wind: WindField = None) -> None:
        if not isinstance(params, QuadrotorParams):
            raise TypeError(f"params must be a cufund.QuadrotorParams, got {type(params).__name__}")
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 2**32:
            raise ValueError(f"n must be an integer in [1, 2^32], got {n!r}")
        cap = limits.current().batch_max_size
        if n > cap:
            raise ValueError(
                f"n must be at most batch_max_size = {cap} vehicles (256 bytes each), got {n}; "
                "raise it with cufund.core.limits.configure(batch_max_size=...)"
            )
        self.params = params
        self._core = _core.dynamics.QuadrotorBatch(params.to_core(), int(n))
        self._wind_fn: Callable[[float, np.ndarray], np.ndarray] | None = None
        self.set_wind(wind)

    @property
    def n(self) -> int:
        """Number of vehicles."""
        return int(self._core.size)

    @property
    def t(self) -> float:
        """Simulated time [s]."""
        return float(self._core.time)

    @t.setter
    def t(self, value: float) -> None:
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise TypeError(f"t must be a real number [s], got {type(value).__name__}")
        if not math.isfinite(value):
            raise ValueError(f"t must be finite [s], got {value!r}")
        self._core.time = float(value)

    # Pickling: parameters, time, every state and held-input row, and the wind (a function must itself pickle).
    _ROWS = ("p", "v", "q", "w", "rotor_speeds", "wind_W", "force_ext_W", "torque_ext_B", "accel_W", "alpha_B")

    def __getstate__(self) -> dict[str, Any]:
        return {
            "params": self.params,
            "n": self.n,
            "t": self.t,
            "wind_fn": self._wind_fn,
            **{name: np.array(getattr(self, name)) for name in self._ROWS},
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        QuadrotorBatch.__init__(self, state["params"], state["n"])
        for name in self._ROWS:
            getattr(self, name)[:] = state[name]
        self._core.time = state["t"]
        self._wind_fn = state["wind_fn"]

    p = property(lambda self: self._core.p, doc="Position p_W [m], (n, 3) view.")
    v = property(lambda self: self._core.v, doc="Velocity v_W [m/s], (n, 3) view.")
    q = property(lambda self: self._core.q, doc="Attitude q_WB [w, x, y, z], (n, 4) view.")
    w = property(lambda self: self._core.w, doc="Body rate w_B [rad/s], (n, 3) view.")
    rotor_speeds = property(lambda self: self._core.rotor_speeds, doc="Rotor speeds [rad/s], (n, 4) view.")
    wind_W = property(lambda self: self._core.wind_W, doc="Wind velocity, world frame [m/s], (n, 3) view.")
    force_ext_W = property(lambda self: self._core.force_ext_W, doc="External force, world [N], (n, 3) view.")
    torque_ext_B = property(lambda self: self._core.torque_ext_B, doc="External torque, body [N m], (n, 3) view.")
    accel_W = property(
        lambda self: self._core.accel_W,
        doc="Acceleration dv_W/dt of the model at the end of the last step [m/s^2], (n, 3) view.",
    )
    alpha_B = property(
        lambda self: self._core.alpha_B,
        doc="Angular acceleration dw_B/dt at the end of the last step [rad/s^2], (n, 3) view.",
    )

    def set_wind(self, wind: WindField) -> None:
        """Constant wind (array (3,) or (n, 3)) [m/s], a function ``wind(t, p_W)``, or None for still air."""
        self._wind_fn = None
        if wind is None:
            self.wind_W[:] = 0.0
        elif callable(wind):
            self._wind_fn = wind
        else:
            self.wind_W[:] = _finite_rows("wind", wind, self.n)

    def reset(self) -> None:
        """All vehicles at the origin, level, at rest, rotors stopped; time 0. Wind and disturbances cleared."""
        self._core.reset()
        self._wind_fn = None

    def hover(self, p_W: np.ndarray | None = None) -> None:
        """Puts every vehicle in steady hover (rotors at hover speed, at rest, level) at ``p_W`` [m]."""
        if p_W is not None:
            self.p[:] = _finite_rows("p_W", p_W, self.n)
        self.v[:] = 0.0
        self.q[:] = (1.0, 0.0, 0.0, 0.0)
        self.w[:] = 0.0
        self.rotor_speeds[:] = self.params.hover_rotor_speed

    def step(self, dt: float, rotor_speed_cmd: np.ndarray, nthreads: int = 0) -> None:
        """Advances every vehicle by ``dt`` [s] holding ``rotor_speed_cmd`` (n, 4) [rad/s] constant.

        Commands are clipped to the rotor-speed limits. ``nthreads=0`` uses every core. Results do not depend
        on the thread count.
        """
        if self._wind_fn is not None:
            self.wind_W[:] = _finite_rows("wind(t, p_W)", self._wind_fn(self.t, self.p.copy()), self.n)
        self._core.step(dt, rotor_speed_cmd, nthreads)


class QuadrotorState:
    """A single vehicle's state as writable views: ``p`` [m], ``v`` [m/s], ``q`` [w, x, y, z], ``w`` [rad/s],
    ``rotor_speeds`` [rad/s]. Copy with :meth:`copy` to keep a snapshot."""

    __slots__ = ("p", "v", "q", "w", "rotor_speeds")

    def __init__(self, p: np.ndarray, v: np.ndarray, q: np.ndarray, w: np.ndarray, rotor_speeds: np.ndarray) -> None:
        self.p, self.v, self.q, self.w, self.rotor_speeds = p, v, q, w, rotor_speeds

    def copy(self) -> QuadrotorState:
        return QuadrotorState(self.p.copy(), self.v.copy(), self.q.copy(), self.w.copy(), self.rotor_speeds.copy())

    def as_vector(self) -> np.ndarray:
        """[p, v, q, w, rotor_speeds] as one (17,) array."""
        return np.concatenate([self.p, self.v, self.q, self.w, self.rotor_speeds])

    def __repr__(self) -> str:
        return (
            f"QuadrotorState(p={self.p.tolist()}, v={self.v.tolist()}, q={self.q.tolist()}, "
            f"w={self.w.tolist()}, rotor_speeds={self.rotor_speeds.tolist()})"
        )


class Quadrotor:
    """One quadrotor. ``step(dt, rotor_speed_cmd)`` with a (4,) command [rad/s]; ``state`` holds views."""

    def __init__(self, params: QuadrotorParams, wind: WindField = None) -> None:
        self._attach(QuadrotorBatch(params, 1, wind))

    def _attach(self, batch: QuadrotorBatch) -> None:
        self._batch = b = batch
        self.state = QuadrotorState(b.p[0], b.v[0], b.q[0], b.w[0], b.rotor_speeds[0])
        self._step = b._core.step
        self._sync_fast_step()

    def _sync_fast_step(self) -> None:
        self.fast_step: Callable[[float, np.ndarray, int], None] | None = (
            self._step if self._batch._wind_fn is None else None
        )
        """:meth:`step` without its Python layer, for a caller's inner loop (the simulator's): the C++
        integrator's ``step(dt, rotor_speed_cmd, nthreads)``, the same arithmetic, the held wind ``wind_W``
        applied; None while a wind *function* is set (:meth:`step` evaluates it). Read it before each step (it
        follows :meth:`set_wind` and :meth:`reset`); never assign it."""

    def __getstate__(self) -> dict[str, Any]:
        return {"batch": self._batch}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self._attach(state["batch"])

    params = property(lambda self: self._batch.params)
    t = property(lambda self: self._batch.t, doc="Simulated time [s].")
    force_ext_W = property(lambda self: self._batch.force_ext_W[0], doc="External force, world [N], (3,) view.")
    torque_ext_B = property(lambda self: self._batch.torque_ext_B[0], doc="External torque, body [N m], (3,) view.")
    wind_W = property(lambda self: self._batch.wind_W[0], doc="Wind velocity, world [m/s], (3,) view.")
    accel_W = property(lambda self: self._batch.accel_W[0], doc="dv_W/dt after the last step [m/s^2], (3,) view.")
    alpha_B = property(lambda self: self._batch.alpha_B[0], doc="dw_B/dt after the last step [rad/s^2], (3,) view.")

    def set_wind(self, wind: WindField) -> None:
        """Constant wind (3,) [m/s], a function ``wind(t, p_W)``, or None."""
        self._batch.set_wind(wind)
        self._sync_fast_step()

    def reset(self) -> None:
        """At the origin, level, at rest, rotors stopped; time 0."""
        self._batch.reset()
        self._sync_fast_step()

    def hover(self, p_W: np.ndarray | None = None) -> None:
        """Steady hover at ``p_W`` [m]: rotors at hover speed, at rest, level."""
        self._batch.hover(None if p_W is None else _finite_rows("p_W", p_W, 1))

    def step(self, dt: float, rotor_speed_cmd: np.ndarray) -> None:
        """Advances by ``dt`` [s] holding ``rotor_speed_cmd`` (4,) [rad/s], clipped to the rotor limits."""
        if self._batch._wind_fn is not None:
            self._batch.step(dt, rotor_speed_cmd)
        else:
            self._step(dt, rotor_speed_cmd, 1)


def _finite_rows(name: str, value: object, n: int) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    if a.shape not in ((3,), (n, 3)):
        raise ValueError(f"{name} must have shape (3,) or ({n}, 3), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {a}")
    return a
