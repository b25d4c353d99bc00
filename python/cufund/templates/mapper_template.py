"""Template: a mapper. Copy, rename, replace the map.

A :class:`cufund.Mapper` integrates measurements into a map that planners can query. This one keeps a 2D
occupancy count of where the vehicle has been (cells of ``resolution`` metres), from the state estimate (``/estimator/odometry``).
"""

from __future__ import annotations

import math
from collections import Counter

import cufund
from cufund.core.messages import Odometry, Topics


class MyMapper(cufund.Mapper):
    name = "my_mapper"

    def __init__(self, resolution: float = 0.25, rate_hz: float = 10.0, topic: str = Topics.ESTIMATE) -> None:
        self.resolution, self.rate_hz, self.topic = resolution, rate_hz, topic
        self.inputs = (topic,)
        self.visits: Counter[tuple[int, int]] = Counter()

    def reset(self) -> None:
        self.visits.clear()

    def integrate(self, t: float, bus: cufund.BusView) -> None:
        state: Odometry | None = bus.latest(self.topic)
        if state is not None:
            cell = (math.floor(state.p_W[0] / self.resolution), math.floor(state.p_W[1] / self.resolution))
            self.visits[cell] += 1
