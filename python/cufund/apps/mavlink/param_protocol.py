"""The MAVLink parameter protocol's table: the run's parameters as a ground station sees them.

The run answers ``get_params`` with the commander's parameters and the controller gains under PX4's names and
units (``MIS_TAKEOFF_ALT``, ``COM_DL_LOSS_T``, ``MPC_XY_P``, ``MC_ROLLRATE_P``, ``MPC_TILTMAX_AIR`` in degrees, ...;
:mod:`cufund.missions.controller_params`). Numeric parameters whose names fit MAVLink's 16 characters are shown
as they are; ``aliases`` may rename others. Every value travels as MAV_PARAM_TYPE_REAL32; indices stay fixed
once given.
"""

from __future__ import annotations

from typing import Any

from pymavlink.dialects.v20 import common as mavlink


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
        return mav.param_value_encode(encode_id(name), float(self.values[name]), mavlink.MAV_PARAM_TYPE_REAL32,
                                      len(self.values), self.index_of(name))
