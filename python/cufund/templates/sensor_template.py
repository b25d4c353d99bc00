"""Template: a sensor. Copy, rename, replace the measurement model.

A :class:`cufund.Sensor` turns ground truth into a measurement on its ``topic``. This one is a position sensor
(e.g. motion capture) with Gaussian noise from its own seeded generator, so runs stay repeatable.

To use it in a scenario YAML (``sensors: {mocap: {kind: my_position_sensor, sigma_m: 0.005}}``), register
:data:`KINDS` (``for k in KINDS: cufund.core.registry.register(k)``) or name it in your package's entry points
(``[project.entry-points."cufund.kinds"] my_sensors = "my_package.my_sensor:KINDS"``). Its kind is of the
registered sensor type ``pose`` (:class:`~cufund.core.messages.Pose` messages: position and attitude, no
velocity; no mounting key). A sensor of a new type lists its
:class:`~cufund.core.registry.SensorType` first: ``SensorType("radar", RadarScan, "T_BR")`` declares the message
its topic carries and the key its mounting is given under (``T_BR: {p: [...], q: [...]}`` in the YAML, handed to
the build as ``ctx.part.extrinsic``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import cufund
from cufund.core.build_context import BuildContext
from cufund.core.messages import Odometry, Pose
from cufund.core.registry import Kind


class MyPositionSensor(cufund.Sensor):
    name = "my_position_sensor"
    topic = cufund.Topic("/sensors/position", Pose)  # a typed topic: the bus checks what is published

    def __init__(
        self, sigma_m: float = 0.01, rate_hz: float = 100.0, seed: int = 0, topic: cufund.Topic | None = None
    ) -> None:
        self.sigma, self.rate_hz, self.seed = sigma_m, rate_hz, seed
        if topic is not None:
            self.topic = topic
        self.rng = np.random.default_rng(seed)

    def reset(self) -> None:
        self.rng = np.random.default_rng(self.seed)

    def measure(self, t: float, truth: Odometry) -> Pose:  # what it measures: no velocity, no body rate
        noisy = truth.p_W + self.sigma * self.rng.standard_normal(3)
        return Pose(t, noisy, truth.q_WB)


@dataclass(frozen=True)
class MyPositionSensorParams:
    """The scenario keys of ``kind: my_position_sensor``."""

    sigma_m: float = 0.01
    """Position noise, 1 sigma per axis [m]."""
    rate_hz: float = 100.0
    """Output rate [Hz]."""


def build(p: MyPositionSensorParams, ctx: BuildContext) -> list[cufund.Component]:
    """The sensor of one scenario entry: its topic (``/sensors/NAME`` unless the entry sets ``topic``) and its
    seed (derived from the scenario seed and the sensor's name) come from ``ctx``."""
    return [MyPositionSensor(p.sigma_m, p.rate_hz, ctx.seed, ctx.part.topic)]


KINDS = [
    Kind(
        "sensor",
        "my_position_sensor",
        MyPositionSensorParams,
        build,
        doc="template: a noisy position sensor (Pose)",
        sensor_type="pose",
    )
]
"""What a plug-in's ``cufund.kinds`` entry point names (sensor types first, then the kinds of them)."""
