"""MAVLink for cufund: the one module of frame conversions (:mod:`.frames`) and cufund as PX4's simulator
(:class:`Px4SimulatorBridge`, SITL over TCP and HITL over serial), and a live run as a PX4 vehicle for ground
stations and MAVSDK (:class:`VehicleEndpoint`, ``cufund serve``). Heavy parts are imported on first use."""

from __future__ import annotations

from typing import Any

__all__ = ["Px4Airframe", "Px4BridgeParams", "Px4Harness", "Px4SimulatorBridge", "VehicleEndpoint", "px4_scenario"]

_LAZY = {
    "Px4SimulatorBridge": "px4_sim",
    "Px4BridgeParams": "px4_sim",
    "px4_scenario": "px4_sim",
    "Px4Airframe": "px4_airframe",
    "Px4Harness": "px4_harness",
    "VehicleEndpoint": "vehicle_endpoint",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'cufund.apps.mavlink' has no attribute {name!r}")
    import importlib

    return getattr(importlib.import_module(f"{__name__}.{module}"), name)
