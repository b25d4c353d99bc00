"""The lockstep simulator: components on the bus, the event scheduler's order, the batched vehicle, and what a run
returns (:class:`SimulationResult`, :class:`RunStatus`)."""

from .lockstep import RunStatus, SimulationResult, Simulator

__all__ = ["RunStatus", "SimulationResult", "Simulator"]
