"""Arming and controller selection as the controllers see them: a commander's :class:`VehicleStatus` on
``Topics.VEHICLE_STATUS`` gates each controller made armable (:func:`make_armable`, done by the controller kinds
when the scenario's planner is a commander; otherwise controllers always fly and never read the status).

- not armed: the rotors stop (the final stage publishes zero rotor speeds) and the controller's state resets;
- armed, landed and idle: the rotors spin at idle and the controller's state resets (no integrator wind-up on
  the ground);
- another controller kind selected: the controller publishes nothing and resets (live pid <-> geometric switch).
"""

from __future__ import annotations

import enum
from typing import Any

import numpy as np

from cufund.core.messages import ActuatorCommand, Topics, VehicleStatus

__all__ = ["IDLE_FRACTION", "Gate", "gate", "gated", "make_armable"]

IDLE_FRACTION = 0.2
"""Idle rotor speed as a fraction of the maximum (PX4's armed-on-ground spin, PWM_MAIN_MIN-like)."""


class Gate(enum.Enum):
    FLY = "fly"
    OFF = "off"
    IDLE = "idle"
    INACTIVE = "inactive"


def gate(bus, kind: str) -> Gate:
    """What the controller of ``kind`` ('pid' or 'geometric') does now, from the latest vehicle status."""
    s: VehicleStatus | None = bus.latest(Topics.VEHICLE_STATUS)
    if s is None:
        return Gate.FLY
    if s.controller and s.controller != kind:
        return Gate.INACTIVE
    if not s.armed:
        return Gate.OFF
    if s.landed and s.mode == "idle":
        return Gate.IDLE
    return Gate.FLY


def make_armable(components) -> None:
    """Lets a commander's vehicle status gate ``components`` (those with an ``armable`` flag)."""
    for c in components:
        if hasattr(c, "armable") and not c.armable:
            c.armable = True
            c.optional_reads = (*c.optional_reads, Topics.VEHICLE_STATUS)


def gated(controller: Any, t: float, bus: Any, kind: str) -> bool:
    """Applies the arming gate to a final control stage (see :mod:`cufund.control.arming`): True when it must not
    fly now (it then reset itself and, disarmed or idle, published the rotor speeds)."""
    if not controller.armable:
        return False
    g = gate(bus, kind)
    if g is Gate.FLY:
        return False
    controller.reset()
    if controller.use_gyro:
        controller.gyro.update()  # keep the IMU queue drained and the filter warm
    if g is not Gate.INACTIVE:
        p = controller.params
        w = 0.0 if g is Gate.OFF else max(p.rotor_speed_min, IDLE_FRACTION * p.rotor_speed_max)
        bus.publish(Topics.ACTUATOR_COMMAND, ActuatorCommand(t, np.full(4, w)))
    return True
