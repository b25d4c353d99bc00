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
        self._probe: Callable[[np.ndarray], np.ndarray] | None = None
        self._probe_period = 0.05
        self._probe_next_t = -math.inf
        self._atmosphere: Any = None
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

    # Pickling: parameters, time, every state and held-input row, the rotor efficiency and speed limit, the
    # surfaces and ground effect, and the wind (a function must itself pickle).
    _ROWS = ("p", "v", "q", "w", "rotor_speeds", "wind_W", "force_ext_W", "torque_ext_B", "accel_W", "alpha_B")
    _GE_FIELDS = (
        "rotor_plane_height",
        "enabled",
        "rotor_radius",
        "rotor_spacing",
        "body_distance",
        "k_body",
        "ceiling_k1",
        "ceiling_k2",
        "min_height",
    )

    def __getstate__(self) -> dict[str, Any]:
        ge = self._core.ground_effect
        return {
            "params": self.params,
            "n": self.n,
            "t": self.t,
            "wind_fn": self._wind_fn,
            "probe": (self._probe, self._probe_period),
            **{name: np.array(getattr(self, name)) for name in self._ROWS},
            "rotor_efficiency": np.array(self.rotor_efficiency),
            "max_rotor_speed": np.array(self.max_rotor_speed),
            "surfaces_z": np.array(self._core.surfaces_z),
            "ground_effect": {f: getattr(ge, f) for f in self._GE_FIELDS},
            "atmosphere": self._atmosphere,
        }

    def __setstate__(self, state: dict[str, Any]) -> None:
        QuadrotorBatch.__init__(self, state["params"], state["n"])
        for name in self._ROWS:
            getattr(self, name)[:] = state[name]
        self._core.time = state["t"]
        self._wind_fn = state["wind_fn"]
        if state.get("probe") is not None:
            self.set_surface_probe(*state["probe"])
        if "rotor_efficiency" in state:
            self._core.set_rotor_efficiency(state["rotor_efficiency"])
            self._core.set_max_rotor_speed(state["max_rotor_speed"])
            self._core.set_surfaces_z(state["surfaces_z"])
            ge = _core.dynamics.GroundEffectParams()
            for f, v in state["ground_effect"].items():
                setattr(ge, f, v)
            self._core.set_ground_effect(ge)
        if state.get("atmosphere") is not None:
            self.set_atmosphere(state["atmosphere"])  # restarted from its seed (filter states are not kept)

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

    def set_surface_probe(self, probe: Callable[[np.ndarray], np.ndarray] | None, period: float = 0.05) -> None:
        """Where the ground effect's floor and ceiling are: ``probe(p_W (n, 3)) -> (n, 2)`` (floor_z, ceiling_z)
        [m] (e.g. :class:`cufund.worlds.surfaces.SurfaceProbe`), called before a step once per ``period`` [s] of
        simulated time; None: the surfaces stay as set (:meth:`set_surfaces_z`)."""
        if isinstance(period, bool) or not isinstance(period, (int, float)) or not 0 < period < math.inf:
            raise ValueError(f"period must be a finite time > 0 [s], got {period!r}")
        self._probe = probe
        self._probe_period = float(period)
        self._probe_next_t = -math.inf

    def _update_surfaces(self) -> None:
        """Looks the floor and ceiling up once the probe's period has passed."""
        t = self.t
        if self._probe is not None and t >= self._probe_next_t:
            self._probe_next_t = t + self._probe_period
            self.set_surfaces_z(self._probe(self.p.copy()))

    @property
    def rotor_efficiency(self) -> np.ndarray:
        """Per-rotor thrust and drag-torque scale in [0, 1] (1: nominal, 0: a stopped or failed motor), (n, 4)
        read-only view; set with :meth:`set_rotor_efficiency`. Persists across steps; :meth:`reset` restores 1."""
        return self._core.rotor_efficiency

    def set_rotor_efficiency(self, eta: Any) -> None:
        """Scales each rotor's thrust and drag torque: ``eta`` (4,) for every vehicle or (n, 4), in [0, 1]."""
        self._core.set_rotor_efficiency(_rows("rotor_efficiency", eta, self.n, 4))

    @property
    def max_rotor_speed(self) -> np.ndarray:
        """Upper clamp of the rotor speed command per vehicle [rad/s], (n,) read-only view (default the
        parameters' ``rotor_speed_max``); set with :meth:`set_max_rotor_speed`. :meth:`reset` restores it."""
        return self._core.max_rotor_speed[:, 0]

    def set_max_rotor_speed(self, omega_max: Any) -> None:
        """Sets the rotor speed limit [rad/s]: a scalar for every vehicle or (n,), finite and >= rotor_speed_min
        (e.g. a battery's sagging voltage). Commands above it are clipped to it."""
        a = np.asarray(omega_max, dtype=float) if not isinstance(omega_max, bool) else np.asarray(np.nan)
        if a.shape not in ((), (self.n,)):
            raise ValueError(f"max_rotor_speed must be a scalar or shape ({self.n},) [rad/s], got shape {a.shape}")
        self._core.set_max_rotor_speed(np.broadcast_to(a, (self.n,)))

    @property
    def surfaces_z(self) -> np.ndarray:
        """(floor_z, ceiling_z) per vehicle [m] that the ground effect reads, (n, 2) read-only view (-inf / +inf:
        none; default floor 0 with the ground plane)."""
        return self._core.surfaces_z

    def set_surfaces_z(self, surfaces_z: Any) -> None:
        """Sets (floor_z, ceiling_z) [m]: (2,) for every vehicle or (n, 2); held until changed or reset."""
        self._core.set_surfaces_z(_rows("surfaces_z", surfaces_z, self.n, 2, allow_inf=True))

    def set_atmosphere(self, params: Any) -> None:
        """The wind from an atmosphere (``cufund.worlds.atmosphere.AtmosphereConfig.to_core(...)``): the C++ step
        writes ``wind_W`` from it once per its update period (replacing :meth:`set_wind`'s); None: off. :meth:`reset`
        restarts it from its seed; a pickled copy restarts it too (its filter states are not kept)."""
        if params is None:
            self._core.clear_atmosphere()
        else:
            self._wind_fn = None  # the atmosphere replaces a wind function
            self._core.set_atmosphere(params)
        self._atmosphere = params

    def set_ground_effect(self, config: Any) -> None:
        """Turns the ground and ceiling effect on (a :class:`cufund.vehicle.ground_effect.GroundEffectConfig`) or
        off (None). It is a model setting: it persists across :meth:`reset`."""
        if config is None:
            self._core.set_ground_effect(_core.dynamics.GroundEffectParams())
        else:
            self._core.set_ground_effect(config.to_core(self.params))

    def reset(self) -> None:
        """All vehicles at the origin, level, at rest, rotors stopped; time 0. Wind and disturbances cleared; rotor
        efficiency 1, rotor speed limit the parameters', floor 0 (with the ground plane), no ceiling."""
        self._core.reset()
        self._wind_fn = None
        self._probe_next_t = -math.inf

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
        if self._probe is not None:
            self._update_surfaces()
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
        b = self._batch
        self.fast_step: Callable[[float, np.ndarray, int], None] | None = None
        """:meth:`step` without its Python layer, for a caller's inner loop (the simulator's): the C++
        integrator's ``step(dt, rotor_speed_cmd, nthreads)``, the same arithmetic, the held wind ``wind_W`` (or the
        atmosphere's) applied; with a surface probe, a thin wrapper that calls it once per its period first; None
        while a wind *function* is set (:meth:`step` evaluates it). Read it before each step (it follows
        :meth:`set_wind` and :meth:`reset`); never assign it."""
        if b._wind_fn is None and b._probe is None:
            self.fast_step = self._step
        elif b._wind_fn is None:
            step, update = self._step, b._update_surfaces

            def probed_step(dt: float, cmd: np.ndarray, nthreads: int) -> None:
                if b._core.time >= b._probe_next_t:
                    update()
                step(dt, cmd, nthreads)

            self.fast_step = probed_step

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

    def set_surface_probe(self, probe: Callable[[np.ndarray], np.ndarray] | None, period: float = 0.05) -> None:
        """The ground effect's floor/ceiling lookup (see :meth:`QuadrotorBatch.set_surface_probe`)."""
        self._batch.set_surface_probe(probe, period)
        self._sync_fast_step()

    @property
    def rotor_efficiency(self) -> np.ndarray:
        """Per-rotor thrust and drag-torque scale in [0, 1], (4,) read-only view (default 1)."""
        return self._batch.rotor_efficiency[0]

    def set_rotor_efficiency(self, eta: Any) -> None:
        """Scales each rotor's thrust and drag torque: (4,) in [0, 1] (0: a stopped motor); persists until reset."""
        self._batch._core.set_rotor_efficiency(_rows("rotor_efficiency", eta, 1, 4, single=True))  # checked once

    @property
    def max_rotor_speed(self) -> float:
        """Upper clamp of the rotor speed command [rad/s] (default the parameters' ``rotor_speed_max``)."""
        return float(self._batch.max_rotor_speed[0])

    def set_max_rotor_speed(self, omega_max: float) -> None:
        """Sets the rotor speed limit [rad/s], a scalar >= rotor_speed_min; persists until reset."""
        a = np.asarray(omega_max, dtype=float) if not isinstance(omega_max, bool) else np.asarray(np.nan)
        if a.shape != ():
            raise ValueError(f"max_rotor_speed must be a scalar [rad/s], got shape {a.shape}")
        self._batch._core.set_max_rotor_speed(a.reshape(1))  # the core checks the value (a battery calls it often)

    @property
    def surfaces_z(self) -> np.ndarray:
        """(floor_z, ceiling_z) [m] the ground effect reads, (2,) read-only view."""
        return self._batch.surfaces_z[0]

    def set_surfaces_z(self, surfaces_z: Any) -> None:
        """Sets (floor_z, ceiling_z) [m] (-inf / +inf: none)."""
        self._batch.set_surfaces_z(_rows("surfaces_z", surfaces_z, 1, 2, single=True, allow_inf=True))

    def set_atmosphere(self, params: Any) -> None:
        """The wind from an atmosphere's C++ constants (see :meth:`QuadrotorBatch.set_atmosphere`), or None."""
        self._batch.set_atmosphere(params)
        self._sync_fast_step()

    def set_ground_effect(self, config: Any) -> None:
        """Ground and ceiling effect on (a GroundEffectConfig) or off (None); persists across reset."""
        self._batch.set_ground_effect(config)

    def reset(self) -> None:
        """At the origin, level, at rest, rotors stopped; time 0."""
        self._batch.reset()
        self._sync_fast_step()

    def hover(self, p_W: np.ndarray | None = None) -> None:
        """Steady hover at ``p_W`` [m]: rotors at hover speed, at rest, level."""
        self._batch.hover(None if p_W is None else _finite_rows("p_W", p_W, 1))

    def step(self, dt: float, rotor_speed_cmd: np.ndarray) -> None:
        """Advances by ``dt`` [s] holding ``rotor_speed_cmd`` (4,) [rad/s], clipped to the rotor limits."""
        if self._batch._wind_fn is not None or self._batch._probe is not None:
            self._batch.step(dt, rotor_speed_cmd)
        else:
            self._step(dt, rotor_speed_cmd, 1)


def _rows(name: str, value: object, n: int, k: int, single: bool = False, allow_inf: bool = False) -> np.ndarray:
    """``value`` as an (n, k) float array: (k,) broadcast to every vehicle, or (n, k) (not with ``single``)."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an array of real numbers, got {type(value).__name__}") from None
    shapes = ((k,),) if single else ((k,), (n, k))
    if a.shape not in shapes:
        raise ValueError(f"{name} must have shape {' or '.join(str(s) for s in shapes)}, got {a.shape}")
    if np.any(np.isnan(a)) or (not allow_inf and not np.all(np.isfinite(a))):
        raise ValueError(f"{name} must be {'real numbers (not NaN)' if allow_inf else 'finite'}, got {a}")
    return np.ascontiguousarray(np.broadcast_to(a, (n, k)))


def _finite_rows(name: str, value: object, n: int) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    if a.shape not in ((3,), (n, 3)):
        raise ValueError(f"{name} must have shape (3,) or ({n}, 3), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {a}")
    return a
