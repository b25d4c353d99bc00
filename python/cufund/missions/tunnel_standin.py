"""TEMPORARY stand-in for engineer D's TunnelDetector while it is being built: publishes the true frames with
1 cm noise and a growing confidence. Reads truth; deleted once cufund.perception.TunnelDetector lands."""

from __future__ import annotations

import numpy as np

from ..components import Component
from ..messages import Topics, TunnelEstimate


class StandInDetector(Component):
    name = "tunnel_detector"
    rate_hz = 5.0
    reads_truth = True
    inputs = (Topics.POINT_CLOUD,)
    outputs = (Topics.TUNNEL_ESTIMATE,)

    def __init__(self, course, seed: int = 0) -> None:
        self.course, self.seed = course, seed

    def reset(self) -> None:
        self.rng = np.random.default_rng(self.seed)
        self.n = 0

    def step(self, t, bus) -> None:
        self.n += 1
        f = self.course.frames
        c = np.array([x.centre_W for x in f]) + self.rng.normal(0, 0.01, (len(f), 3))
        nrm = np.array([x.axis_W for x in f])
        sizes = np.array([[x.width, x.height] for x in f])
        conf = np.full(len(f), min(1.0, self.n / 10))
        bus.publish(Topics.TUNNEL_ESTIMATE, TunnelEstimate(t, c, nrm, sizes, conf, self.n))
