"""Vehicle commands as plain data: what a ground station's JSON or a MAVLink endpoint produces, parsed and validated
into a :class:`Command`, and the :class:`CommandAck` a :class:`cufund.missions.Commander` answers with.

Positions are world ENU [m], velocities [m/s], yaw [rad] about world z from east, quaternions ``[w, x, y, z]``,
thrust [N]. Bad input raises ``ValueError`` naming the field.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["ACK_RESULTS", "COMMANDS", "Command", "CommandAck", "MissionItem", "parse_command"]

ACK_RESULTS = ("accepted", "denied", "unsupported", "failed", "in_progress")
"""CommandAck results, mirroring MAV_RESULT (ACCEPTED, DENIED, UNSUPPORTED, FAILED, IN_PROGRESS)."""

COMMANDS = (
    "arm",
    "disarm",
    "takeoff",
    "land",
    "rtl",
    "hold",
    "goto",
    "mission_upload",
    "mission_start",
    "mission_clear",
    "flight_mode",
    "controller",
    "offboard_position",
    "offboard_velocity",
    "offboard_attitude",
    "set_param",
    "get_params",
)
"""The command names :func:`parse_command` accepts."""

FLIGHT_MODES = ("position", "velocity", "attitude")
CONTROLLERS = ("pid", "geometric")


@dataclass(frozen=True)
class MissionItem:
    """One waypoint of a mission: fly to ``p_W`` [m], face ``yaw`` [rad] (None: keep the heading), wait
    ``hold_s`` [s] once there."""

    p_W: tuple[float, float, float]
    yaw: float | None = None
    hold_s: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return {"p_W": list(self.p_W), "yaw": self.yaw, "hold_s": self.hold_s}


@dataclass(frozen=True)
class Command:
    """A validated command (``command`` is one of :data:`COMMANDS`); the fields a command does not use are None."""

    command: str
    altitude: float | None = None
    """takeoff: height above home [m] (None: the commander's default)."""
    p_W: tuple[float, float, float] | None = None
    """goto, offboard_position: target position [m]."""
    v_W: tuple[float, float, float] | None = None
    """offboard_position (feed-forward), offboard_velocity: velocity [m/s]."""
    yaw: float | None = None
    """goto, offboard_*: heading [rad] (None: keep)."""
    items: tuple[MissionItem, ...] = ()
    """mission_upload: the waypoints."""
    mode: str | None = None
    """flight_mode: 'position', 'velocity' or 'attitude'."""
    kind: str | None = None
    """controller: 'pid' or 'geometric'."""
    q_WB: tuple[float, float, float, float] | None = None
    """offboard_attitude: attitude [w, x, y, z] (normalised)."""
    thrust: float | None = None
    """offboard_attitude: collective thrust [N] (None: hover thrust)."""
    name: str | None = None
    """set_param: parameter name."""
    value: Any = None
    """set_param: parameter value."""
    force: bool = False
    """disarm: also in flight (the rotors stop and the vehicle falls)."""
    seq: int = 0
    """mission_start: the item to start from (MAVLink's MISSION_START first item / MISSION_SET_CURRENT)."""
    extra: Mapping[str, Any] = field(default_factory=dict)
    """Anything else the dict carried (e.g. a client's request id), passed through untouched."""

    @classmethod
    def from_dict(cls, data: Any) -> Command:
        return parse_command(data)

    def to_data(self) -> dict[str, Any]:
        """The command as the plain data :func:`parse_command` reads back: ``command`` and the fields it sets (a
        scenario's ``planner.script`` written to a run folder's config.yaml reloads as the same commands)."""
        out: dict[str, Any] = {"command": self.command}
        for name in _KEYS[self.command]:
            value = getattr(self, name)
            if name == "items":
                out[name] = [item.to_dict() for item in value]
            elif value is not None:
                out[name] = list(value) if isinstance(value, tuple) else value
        out.update(self.extra)
        return out


@dataclass(frozen=True)
class CommandAck:
    """The answer to a command: ``result`` one of :data:`ACK_RESULTS`, ``message`` says why in words."""

    command: str
    result: str
    message: str = ""
    data: Any = None
    """A reply's payload (get_params: the parameters by name)."""

    def __post_init__(self) -> None:
        if self.result not in ACK_RESULTS:
            raise ValueError(f"CommandAck.result must be one of {', '.join(ACK_RESULTS)}, got {self.result!r}")

    @property
    def ok(self) -> bool:
        return self.result in ("accepted", "in_progress")

    def to_dict(self) -> dict[str, Any]:
        out = {"command": self.command, "result": self.result, "message": self.message}
        if self.data is not None:
            out["data"] = self.data
        return out


def _number(name: str, v: Any, positive: bool = False, allow_zero: bool = True) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(float(v)):
        raise ValueError(f"{name} must be a finite number, got {v!r}")
    v = float(v)
    if positive and (v < 0 or (v == 0 and not allow_zero)):
        raise ValueError(f"{name} must be {'>= 0' if allow_zero else '> 0'}, got {v!r}")
    return v


def _vector(name: str, v: Any, n: int = 3, unit: str = "[m]") -> tuple[float, ...]:
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be {n} finite numbers {unit}, got {v!r}") from None
    if a.shape != (n,) or not np.all(np.isfinite(a)) or any(isinstance(x, bool) for x in np.ravel(v)):
        raise ValueError(f"{name} must be {n} finite numbers {unit}, got {v!r}")
    if np.any(np.abs(a) > 1e5):
        raise ValueError(f"{name} must lie within 1e5 of zero {unit}, got {v!r}")
    return tuple(float(x) for x in a)


def _item(i: int, v: Any) -> MissionItem:
    where = f"items[{i}]"
    if isinstance(v, Mapping):
        unknown = sorted(set(v) - {"p_W", "yaw", "hold_s"})
        if unknown:
            raise ValueError(f"{where}: unknown key {unknown[0]!r}; expected p_W, yaw, hold_s")
        if "p_W" not in v:
            raise ValueError(f"{where}.p_W is missing")
        p = _vector(f"{where}.p_W", v["p_W"])
        yaw = v.get("yaw")
        hold = v.get("hold_s", 0.0)
    else:
        if not isinstance(v, (list, tuple, np.ndarray)) or len(v) not in (3, 4, 5):
            raise ValueError(
                f"{where} must be [x, y, z], [x, y, z, yaw], [x, y, z, yaw, hold_s] or a dict with p_W, got {v!r}"
            )
        p = _vector(f"{where}.p_W", list(v[:3]))
        yaw = v[3] if len(v) > 3 else None
        hold = v[4] if len(v) > 4 else 0.0
    yaw = None if yaw is None else _number(f"{where}.yaw", yaw)
    hold = _number(f"{where}.hold_s", hold, positive=True)
    return MissionItem(p, yaw, hold)  # type: ignore[arg-type]


_KEYS: dict[str, tuple[str, ...]] = {
    "arm": (),
    "disarm": ("force",),
    "takeoff": ("altitude",),
    "land": (),
    "rtl": (),
    "hold": (),
    "goto": ("p_W", "yaw"),
    "mission_upload": ("items",),
    "mission_start": ("seq",),
    "mission_clear": (),
    "flight_mode": ("mode",),
    "controller": ("kind",),
    "offboard_position": ("p_W", "v_W", "yaw"),
    "offboard_velocity": ("v_W", "yaw"),
    "offboard_attitude": ("q_WB", "thrust"),
    "set_param": ("name", "value"),
    "get_params": (),
}
_PASS_THROUGH = ("id", "request_id", "source")


def parse_command(data: Any) -> Command:
    """A :class:`Command` from a plain dict (``{"command": "goto", "p_W": [1, 2, 1.5]}``), a bare command name
    (``"arm"``) or a :class:`Command` (returned as is). Raises ``ValueError`` naming the field."""
    if isinstance(data, Command):
        return data
    if isinstance(data, str):
        data = {"command": data}
    if not isinstance(data, Mapping):
        # a ValueError (not TypeError) for any bad input: clients map one exception to one error reply
        raise ValueError(f"a command must be a dict with a 'command' key, got {type(data).__name__}")
    name = data.get("command")
    if not isinstance(name, str) or name not in _KEYS:
        raise ValueError(f"command must be one of {', '.join(COMMANDS)}, got {name!r}")
    allowed = _KEYS[name]
    unknown = sorted(k for k in data if k != "command" and k not in allowed and k not in _PASS_THROUGH)
    if unknown:
        raise ValueError(f"{name}: unknown field {unknown[0]!r}; expected {', '.join(allowed) or 'no fields'}")
    kw: dict[str, Any] = {"extra": {k: data[k] for k in _PASS_THROUGH if k in data}}
    if "yaw" in allowed and data.get("yaw") is not None:
        kw["yaw"] = _number("yaw", data["yaw"])
    if name == "disarm":
        force = data.get("force", False)
        if not isinstance(force, bool):
            raise ValueError(f"force must be true or false, got {force!r}")
        kw["force"] = force
    elif name == "takeoff":
        if data.get("altitude") is not None:
            kw["altitude"] = _number("altitude", data["altitude"], positive=True, allow_zero=False)
            if kw["altitude"] > 1e4:
                raise ValueError(f"altitude must be at most 1e4 m, got {data['altitude']!r}")
    elif name in ("goto", "offboard_position"):
        if "p_W" not in data:
            raise ValueError(f"{name}: p_W is missing ([x, y, z] in metres, ENU)")
        kw["p_W"] = _vector("p_W", data["p_W"])
        if name == "offboard_position" and data.get("v_W") is not None:
            kw["v_W"] = _vector("v_W", data["v_W"], unit="[m/s]")
    elif name == "offboard_velocity":
        if "v_W" not in data:
            raise ValueError("offboard_velocity: v_W is missing ([vx, vy, vz] in m/s, ENU)")
        kw["v_W"] = _vector("v_W", data["v_W"], unit="[m/s]")
    elif name == "offboard_attitude":
        if "q_WB" not in data:
            raise ValueError("offboard_attitude: q_WB is missing ([w, x, y, z])")
        q = np.asarray(_vector("q_WB", data["q_WB"], 4, "[w, x, y, z]"))
        n = float(np.linalg.norm(q))
        if n < 1e-6:
            raise ValueError(f"q_WB must be a non-zero quaternion [w, x, y, z], got {data['q_WB']!r}")
        kw["q_WB"] = tuple(float(x) for x in q / n)
        if data.get("thrust") is not None:
            kw["thrust"] = _number("thrust", data["thrust"], positive=True)
    elif name == "mission_upload":
        items = data.get("items")
        if not isinstance(items, (list, tuple)):
            raise ValueError(f"items must be a list of waypoints [[x, y, z], ...], got {items!r}")
        if len(items) > 10000:
            raise ValueError(f"items must hold at most 10000 waypoints, got {len(items)}")
        kw["items"] = tuple(_item(i, v) for i, v in enumerate(items))
    elif name == "mission_start":
        seq = data.get("seq", 0)
        if isinstance(seq, bool) or not isinstance(seq, (int, np.integer)) or seq < 0:
            raise ValueError(f"seq must be an item index >= 0, got {seq!r}")
        kw["seq"] = int(seq)
    elif name == "flight_mode":
        mode = data.get("mode")
        if mode not in FLIGHT_MODES:
            raise ValueError(f"mode must be one of {', '.join(FLIGHT_MODES)}, got {mode!r}")
        kw["mode"] = mode
    elif name == "controller":
        kind = data.get("kind")
        if kind not in CONTROLLERS:
            raise ValueError(f"kind must be one of {', '.join(CONTROLLERS)}, got {kind!r}")
        kw["kind"] = kind
    elif name == "set_param":
        pname = data.get("name")
        if not isinstance(pname, str) or not pname:
            raise ValueError(f"name must be a parameter name, got {pname!r}")
        if "value" not in data:
            raise ValueError("set_param: value is missing")
        kw["name"] = pname
        kw["value"] = data["value"]
    return Command(name, **kw)
