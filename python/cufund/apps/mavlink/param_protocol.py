"""The MAVLink parameter protocol (vehicle side): :class:`ParamTable`, the run's parameters as a ground station
sees them, their bounds (:data:`PX4_BOUNDS`), and :class:`ParamProtocol`, which answers PARAM_REQUEST_LIST,
PARAM_REQUEST_READ and PARAM_SET through the run's commander.

The run answers ``get_params`` with the commander's parameters and the controller gains under PX4's names and
units (``MIS_TAKEOFF_ALT``, ``COM_DL_LOSS_T``, ``MPC_XY_P``, ``MC_ROLLRATE_P``, ``MPC_TILTMAX_AIR`` in degrees, ...;
:mod:`cufund.missions.controller_params`). Numeric parameters whose names fit MAVLink's 16 characters are shown
as they are; ``aliases`` may rename others. Every value travels as MAV_PARAM_TYPE_REAL32; indices stay fixed
once given.

PARAM_SET of an unknown name is answered with a STATUSTEXT; of a non-finite value or one outside the parameter's
bounds it is not applied, and PARAM_VALUE echoes the current value (how a MAVLink parameter server refuses).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from pymavlink.dialects.v20 import common as mavlink

_INF = math.inf

# cufund's rate-loop gains act on angular acceleration, PX4's on a normalised torque (see
# cufund.missions.controller_params): PX4's bounds are carried over scaled by cufund's default / PX4's default.
_RATE_P, _RATE_I, _RATE_D = 25.0 / 0.15, 10.0 / 0.2, 0.2 / 0.003
_YAW_P, _YAW_I = 12.0 / 0.2, 5.0 / 0.1

PX4_BOUNDS: dict[str, tuple[float, float]] = {
    # navigator/mission_params.c: MIS_TAKEOFF_ALT @min 0 @max 80 [m]
    "MIS_TAKEOFF_ALT": (0.0, 80.0),
    # mc_pos_control/multicopter_takeoff_land_params.c: MPC_TKO_SPEED @min 1 @max 5 [m/s]; MPC_LAND_SPEED
    # @min 0.6 (no max); MPC_LAND_ALT2 @min 0 @max 122 [m]. cufund's small vehicles climb at 0.5 m/s and land at
    # 0.3 m/s by default, below PX4's minima: the lower bounds are cufund's (> 0), the upper ones PX4's.
    "MPC_TKO_SPEED": (0.05, 5.0),
    "MPC_LAND_SPEED": (0.05, _INF),
    "MPC_LAND_ALT2": (0.0, 122.0),
    # mc_pos_control/multicopter_autonomous_params.c: MPC_XY_CRUISE @min 3 @max 20 [m/s] (cufund's default
    # 1 m/s: lower bound cufund's); MPC_ACC_HOR @min 2 @max 15 [m/s^2]; MPC_JERK_AUTO @min 1 @max 80 [m/s^3]
    "MPC_XY_CRUISE": (0.1, 20.0),
    "MPC_ACC_HOR": (2.0, 15.0),
    "MPC_JERK_AUTO": (1.0, 80.0),
    # navigator/navigator_params.c: NAV_ACC_RAD @min 0.05 @max 200 [m]
    "NAV_ACC_RAD": (0.05, 200.0),
    # commander/commander_params.c: COM_OF_LOSS_T @min 0 @max 60 [s]; COM_DL_LOSS_T @min 0 @max 300 [s] (an
    # older release's bound; newer ones say @min 5, which would refuse the short losses cufund's indoor tests
    # fly); COM_DISARM_PRFLT has no bounds in PX4 (cufund's CommanderParams: >= 0)
    "COM_OF_LOSS_T": (0.0, 60.0),
    "COM_DL_LOSS_T": (0.0, 300.0),
    # navigator/rtl_params.c: RTL_RETURN_ALT @min 0 @max 150 [m]
    "RTL_RETURN_ALT": (0.0, 150.0),
    # mc_pos_control/multicopter_position_control_gain_params.c: MPC_XY_P @min 0 @max 2, MPC_Z_P @min 0 @max 1.5,
    # MPC_XY_VEL_P_ACC @min 1.2 @max 5, MPC_Z_VEL_P_ACC @min 2 @max 15, MPC_XY_VEL_I_ACC @min 0 @max 60,
    # MPC_Z_VEL_I_ACC @min 0.2 @max 3, MPC_XY_VEL_D_ACC @min 0.1 @max 2, MPC_Z_VEL_D_ACC @min 0 @max 2. cufund's
    # built-in scenarios fly stiffer position loops (xy_p = z_p = 3, xy_vel_p = 8): those upper bounds are doubled
    # from the scenarios' values (6, 6, 16); and xy_vel_d may be 0 (cufund's default).
    "MPC_XY_P": (0.0, 6.0),
    "MPC_Z_P": (0.0, 6.0),
    "MPC_XY_VEL_P_ACC": (1.2, 16.0),
    "MPC_Z_VEL_P_ACC": (2.0, 15.0),
    "MPC_XY_VEL_I_ACC": (0.0, 60.0),
    "MPC_Z_VEL_I_ACC": (0.2, 3.0),
    "MPC_XY_VEL_D_ACC": (0.0, 2.0),
    "MPC_Z_VEL_D_ACC": (0.0, 2.0),
    # mc_pos_control/multicopter_position_control_limits_params.c: MPC_XY_VEL_MAX @min 0 @max 20,
    # MPC_Z_VEL_MAX_UP @min 0.5 @max 8, MPC_Z_VEL_MAX_DN @min 0.5 @max 4 [m/s]; MPC_TILTMAX_AIR @min 20 @max 89
    # [deg]; MPC_THR_MIN @min 0.05 @max 0.5, MPC_THR_MAX @min 0 @max 1
    "MPC_XY_VEL_MAX": (0.0, 20.0),
    "MPC_Z_VEL_MAX_UP": (0.5, 8.0),
    "MPC_Z_VEL_MAX_DN": (0.5, 4.0),
    "MPC_TILTMAX_AIR": (20.0, 89.0),
    "MPC_THR_MIN": (0.05, 0.5),
    "MPC_THR_MAX": (0.0, 1.0),
    # mc_att_control/mc_att_control_params.c: MC_ROLL_P, MC_PITCH_P @min 0 @max 12, MC_YAW_P @min 0 @max 5 [1/s];
    # MC_ROLLRATE_MAX, MC_PITCHRATE_MAX, MC_YAWRATE_MAX @min 0 @max 1800 [deg/s]
    "MC_ROLL_P": (0.0, 12.0),
    "MC_PITCH_P": (0.0, 12.0),
    "MC_YAW_P": (0.0, 5.0),
    "MC_ROLLRATE_MAX": (0.0, 1800.0),
    "MC_PITCHRATE_MAX": (0.0, 1800.0),
    "MC_YAWRATE_MAX": (0.0, 1800.0),
    # mc_rate_control/mc_rate_control_params.c (PX4 default 0.15 / 0.2 / 0.003 for roll and pitch P / I / D, 0.2
    # / 0.1 / 0 for yaw): MC_ROLLRATE_P @min 0.01 @max 0.5, MC_PITCHRATE_P @min 0.01 @max 0.6, MC_YAWRATE_P
    # @min 0 @max 0.6, MC_ROLLRATE_D @min 0 @max 0.01, the I gains and the other D gains @min 0 (no max); scaled
    "MC_ROLLRATE_P": (0.01 * _RATE_P, 0.5 * _RATE_P),
    "MC_PITCHRATE_P": (0.01 * _RATE_P, 0.6 * _RATE_P),
    "MC_YAWRATE_P": (0.0, 0.6 * _YAW_P),
    "MC_ROLLRATE_I": (0.0, _INF),
    "MC_PITCHRATE_I": (0.0, _INF),
    "MC_YAWRATE_I": (0.0, _INF),
    "MC_ROLLRATE_D": (0.0, 0.01 * _RATE_D),
    "MC_PITCHRATE_D": (0.0, _INF),
    "MC_YAWRATE_D": (0.0, _INF),
}
"""PX4's parameter metadata (``@min`` / ``@max`` in PX4-Autopilot's ``*_params.c``, v1.14-v1.15) for the
parameters cufund implements, in wire units; a PARAM_SET outside them is refused. Parameters PX4 does not have
(``GEO_*``, cufund's own commander fields) are bounded only by cufund's own validation."""


def out_of_bounds(name: str, value: float) -> str | None:
    """Why ``value`` cannot be set on ``name`` (non-finite, or outside :data:`PX4_BOUNDS`); None if it can."""
    if not math.isfinite(value):
        return f"{name}: not a finite value"
    lo, hi = PX4_BOUNDS.get(name, (-_INF, _INF))
    if not lo <= value <= hi:
        return f"{name} {value:g} out of [{lo:g}, {hi:g}]"
    return None


def encode_id(name: str) -> bytes:
    return name.encode("ascii", "replace")[:16]


def decode_id(raw: Any) -> str:
    """A PARAM_* param_id (bytes or str, NUL-padded or not) as a str."""
    if isinstance(raw, (bytes, bytearray)):
        raw = bytes(raw).split(b"\0", 1)[0].decode("ascii", "replace")
    return str(raw).split("\0", 1)[0]


class ParamTable:
    """Wire names, values and fixed indices of the run's parameters, refreshed from ``get_params`` answers."""

    def __init__(self, aliases: dict[str, tuple[str, float]] | None = None) -> None:
        self.aliases = dict(aliases or {})
        """run name -> (wire name, wire value per run value)."""
        self._run_of: dict[str, tuple[str, float]] = {}  # wire name -> (run name, scale)
        self.values: dict[str, float] = {}  # wire name -> wire value, in index order
        self.loaded = False

    def update(self, run_values: dict[str, Any]) -> None:
        """Takes the run's {name: value}; non-numeric values and names longer than 16 characters are left out."""
        for name, value in run_values.items():
            if isinstance(value, bool):
                value = float(value)
            if not isinstance(value, (int, float)) or isinstance(value, complex):
                continue
            wire, scale = self.aliases.get(name, (name, 1.0))
            if len(wire) > 16 or not wire.isascii():
                continue
            self._run_of[wire] = (name, scale)
            self.values[wire] = float(value) * scale
        self.loaded = True

    def __len__(self) -> int:
        return len(self.values)

    def index_of(self, name: str) -> int:
        for i, k in enumerate(self.values):
            if k == name:
                return i
        return -1

    def name_at(self, index: int) -> str | None:
        if 0 <= index < len(self.values):
            return list(self.values)[index]
        return None

    def to_run(self, wire_name: str, wire_value: float) -> tuple[str, float] | None:
        """The run's (name, value) of a PARAM_SET (None: unknown parameter)."""
        run = self._run_of.get(wire_name)
        if run is None:
            return None
        return run[0], float(wire_value) / run[1]

    def from_run(self, run_name: str, run_value: Any) -> tuple[str, float] | None:
        wire, scale = self.aliases.get(run_name, (run_name, 1.0))
        if wire not in self.values or isinstance(run_value, str):
            return None
        return wire, float(run_value) * scale

    def param_value(self, mav: mavlink.MAVLink, name: str):
        """PARAM_VALUE of one parameter (None if unknown)."""
        if name not in self.values:
            return None
        return mav.param_value_encode(
            encode_id(name),
            float(self.values[name]),
            mavlink.MAV_PARAM_TYPE_REAL32,
            len(self.values),
            self.index_of(name),
        )


class ParamProtocol:
    """Parameter micro-service: ``handle(msg, send)`` for PARAM_REQUEST_LIST / PARAM_REQUEST_READ / PARAM_SET.

    ``submit(cmd) -> Future[CommandAck]`` reaches the run's commander (``get_params`` / ``set_param``);
    ``defer(fn, *args)`` runs ``fn`` on the caller's loop thread (the commander answers on its own thread);
    ``send(factory)`` sends on the link the request came from, ``warn(text)`` a STATUSTEXT warning there.
    """

    def __init__(self, submit: Callable, defer: Callable, aliases: dict[str, tuple[str, float]] | None = None) -> None:
        self.table = ParamTable(aliases)
        self._submit, self._defer = submit, defer
        self.refused = 0

    def refresh(self, then: Callable | None = None) -> None:
        """Asks the commander for its parameters; the table is updated (and ``then()`` called) on the loop."""

        def done(f: Any) -> None:
            try:
                ack = f.result()
            except Exception:
                return
            if isinstance(ack.data, dict):
                self._defer(self.table.update, ack.data)
            if then is not None:
                self._defer(then)

        try:
            self._submit({"command": "get_params"}).add_done_callback(done)
        except ValueError:
            pass

    def _value(self, send: Callable, name: str) -> None:
        if name in self.table.values:
            send(lambda mav: self.table.param_value(mav, name))

    def handle(self, msg: Any, send: Callable, warn: Callable) -> None:
        kind = msg.get_type()
        table = self.table
        if kind == "PARAM_REQUEST_LIST":

            def send_all() -> None:
                for n in list(table.values):
                    self._value(send, n)

            self.refresh(send_all)
            return
        if kind == "PARAM_REQUEST_READ":
            found = decode_id(msg.param_id) if msg.param_index < 0 else table.name_at(msg.param_index)
            if found is not None:
                read: str = found
                self.refresh(lambda: self._value(send, read))
            return
        if kind != "PARAM_SET":
            return
        name = decode_id(msg.param_id)
        run = table.to_run(name, msg.param_value)
        if run is None:
            warn(f"unknown parameter {name}")
            return
        why = out_of_bounds(name, float(msg.param_value))
        if why is not None:  # not applied: the current value answers
            self.refused += 1
            warn(why)
            self._value(send, name)
            return

        def applied(ack: Any) -> None:
            if ack.result == "accepted" and isinstance(ack.data, dict):
                for k, v in ack.data.items():
                    wire = table.from_run(k, v)
                    if wire is not None:
                        table.values[wire[0]] = wire[1]
            elif ack.message:
                warn(ack.message)
            self._value(send, name)

        try:
            fut = self._submit({"command": "set_param", "name": run[0], "value": run[1]})
        except ValueError:
            return
        fut.add_done_callback(lambda f: self._defer(applied, f.result()) if not f.exception() else None)
