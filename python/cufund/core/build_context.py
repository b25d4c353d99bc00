"""What a scenario kind's ``build(params, ctx)`` may read and call: the :class:`BuildContext` protocol.

The scenario builder (:class:`cufund.scenarios.build.ScenarioBuildContext`) implements it. A kind reads the
scenario (``config``), the vehicle's params, the world, the part being built (``part``, ``where``, ``seed``) and
the sensors (:meth:`~BuildContext.sensor_of_type`, :meth:`~BuildContext.imu_params`), may build another part
(:meth:`~BuildContext.build`), and contributes to the run only through the declared calls — never by writing
attributes (the builder refuses unknown ones):

- :meth:`~BuildContext.set_reference`: the reference a planner flies (tracking error is measured over its path);
- :meth:`~BuildContext.set_done_condition`: when the run ends (a planner or mission that learns its landing time
  in flight);
- :meth:`~BuildContext.set_commander`: the vehicle commander whose status gates the controllers built after it;
- :meth:`~BuildContext.add_metric_hook`: figures merged into the run's ``metrics.json``;
- :meth:`~BuildContext.add_output_hook`: files a part writes into the run folder.

This module sits in ``core`` so that every kind, whatever its layer, can name the protocol; what it reads
(the scenario, the vehicle's params, the world) is typed ``Any`` here because those types live above ``core``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

__all__ = ["BuildContext", "DoneCondition", "MetricHook", "OutputHook", "PartView"]

DoneCondition = Callable[[float, Any], bool]
"""``done(t, truth) -> bool``: the run ends (completed) at the first ground-truth record where it holds; ``truth``
is a :class:`cufund.core.messages.Odometry` (a harness check, never a flight input)."""
MetricHook = Callable[[Any], dict[str, Any]]
"""``hook(result) -> dict``: figures merged into the run's metrics (``result``: a
:class:`cufund.simulator.SimulationResult`), after the generic ones, so a part may refine a generic figure."""
OutputHook = Callable[..., None]
"""``hook(run, out, **kw)``: writes a part's own files (plots, tables) into the run folder ``out``; ``run`` is the
finished :class:`cufund.scenarios.build.ScenarioRun`."""


class PartView(Protocol):
    """One part of the scenario as a kind sees it (a :class:`cufund.scenarios.schema.PartSpec`)."""

    @property
    def kind(self) -> str: ...

    @property
    def params(self) -> Any:
        """The kind's frozen params dataclass."""

    @property
    def latency_s(self) -> float: ...

    @property
    def phase_s(self) -> float: ...

    @property
    def topic(self) -> Any:
        """Sensors: the :class:`cufund.core.topics.Topic` it publishes on (typed with its sensor type's message)."""

    @property
    def extrinsic(self) -> Any:
        """Mounted sensors: the sensor's pose in the body frame (a :class:`cufund.sensors.Transform`), or None."""

    @property
    def sensor_type(self) -> str | None:
        """Sensors: the name of its registered :class:`cufund.core.registry.SensorType`."""


class BuildContext(Protocol):
    """What a kind's ``build(params, ctx)`` may read and call (see the module docstring)."""

    @property
    def config(self) -> Any:
        """The validated scenario (a :class:`cufund.scenarios.ScenarioConfig`)."""

    @property
    def vehicle(self) -> Any:
        """The vehicle's params (a :class:`cufund.vehicle.QuadrotorParams`)."""

    @property
    def base_dir(self) -> str | None:
        """Where the scenario file lies (relative paths in it resolve from there), or None."""

    @property
    def realism(self) -> Any:
        """The scenario's resolved realism profile and the errors drawn for this run (a
        :class:`cufund.scenarios.realism.Realism`; its ``profile`` is ``ideal`` or ``realistic``). Read-only, and
        for the simulated parts only: a sensor kind gives its simulated sensor ``realism.simulated_imu(...)``,
        ``simulated_lidar(...)``, ``simulated_extrinsic(...)``; flight software keeps the stated extrinsics
        (``sensor_of_type``, ``imu_params``) and the nominal ``vehicle``."""

    @property
    def world(self) -> Any:
        """The scenario's world (a :class:`cufund.worlds.World`), or None without one (and while the world itself
        is being built)."""

    @property
    def part(self) -> PartView:
        """The part being built."""

    @property
    def where(self) -> str:
        """Its place in the scenario, for messages: ``sensors.lidar``, ``planner``, ..."""

    @property
    def seed(self) -> int:
        """The seed of its random stream (:meth:`seed_for` of ``where``)."""

    @property
    def reference(self) -> Any:
        """The reference a planner declared with :meth:`set_reference`, or None."""

    @property
    def tracking_path(self) -> Any:
        """The part of the reference tracking error is measured over, or None."""

    @property
    def commander(self) -> Any:
        """The vehicle commander declared with :meth:`set_commander`, or None: with one, the controllers built
        after it are gated by its vehicle status."""

    def seed_for(self, where: str) -> int:
        """The seed of the random stream of the part at ``where``: derived from the scenario seed and the name, so
        adding a part does not change another's stream."""
        ...

    def require_world(self) -> Any:
        """The world; a ConfigError naming the part when the scenario has none. The world is the truth: the
        builder records who reads it (``world`` or this) and simulated sensors may, flight software may not."""
        ...

    def truth_world_for_metrics(self) -> Any:
        """The world (or None) for harness-only truth consumers (metrics, collision checks, plots), not recorded
        as a read: never hand it to flight software."""
        ...

    def sensor_of_type(self, sensor_type: str, name: str = "", where: str = "") -> tuple[str, PartView]:
        """The sensor called ``name``, or the only sensor of ``sensor_type`` (or the one named after the type), as
        ``(name, spec)``; a ConfigError naming ``where`` otherwise."""
        ...

    def imu_params(self) -> Any:
        """The IMU's params with its mounting applied (None without an IMU)."""
        ...

    def build(self, group: str, spec: PartView, where: str) -> Any:
        """Builds another part (e.g. a second controller to switch to in flight): the world, or a list of
        components. ``part``, ``where`` and ``seed`` are the caller's again afterwards."""
        ...

    def set_reference(self, reference: Any, tracking_path: Any = None) -> None:
        """A planner declares the reference it flies (and the part of it tracking error is measured over)."""
        ...

    def set_done_condition(self, done: DoneCondition) -> None:
        """Declares when the run ends (one part per scenario may)."""
        ...

    def set_commander(self, commander: Any) -> None:
        """Declares the vehicle commander: the controllers built from here on are gated by its vehicle status."""
        ...

    def add_metric_hook(self, hook: MetricHook) -> None:
        """Adds figures to the run's metrics (see :data:`MetricHook`)."""
        ...

    def add_output_hook(self, hook: OutputHook) -> None:
        """Adds files to the run folder (see :data:`OutputHook`)."""
        ...
