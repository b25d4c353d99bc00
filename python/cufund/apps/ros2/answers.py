"""The lockstep answers on ``/cufund/step_ack`` (:data:`~cufund.apps.ros2.config.ACK_TOPIC`) that the bridge and
a ``ros2_external`` part wait for: a node answers simulated time t with a ``std_msgs/msg/Header`` whose
``frame_id`` is its name and whose ``stamp`` is at or after t, and announces itself before the first step with an
answer stamped -1 s."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from .config import ACK_TOPIC
from .dds import QOS, DdsParticipant

__all__ = ["Ros2Timeout", "StepAnswers"]

NS = 1_000_000_000
_NEVER = -(2**62)


class Ros2Timeout(RuntimeError):
    """A lockstep node did not answer within ``timeout_s``."""


class StepAnswers:
    """The answers one participant has received: the nodes that announced themselves (kept for the participant's
    life: a node announces itself once) and the latest time each has answered (dropped at each new run)."""

    def __init__(self, dds: DdsParticipant, timeout_s: float) -> None:
        self.reader = dds.reader(ACK_TOPIC, "std_msgs/msg/Header", QOS["ack"])
        self.timeout_s = timeout_s
        self.announced: set[str] = set()
        self.latest: dict[str, int] = {}
        self._participant = dds.participant
        self._waitset: Any = None

    def new_run(self) -> None:
        """Forgets the answers of the last run (the announcements stay)."""
        self.take()
        self.latest = {}

    def take(self) -> None:
        for s in self.reader.take(N=1000):
            info = getattr(s, "sample_info", None)
            if info is not None and not info.valid_data:
                continue
            ns = int(s.stamp.sec) * NS + int(s.stamp.nanosec)
            self.announced.add(s.frame_id)
            if ns > self.latest.get(s.frame_id, _NEVER):
                self.latest[s.frame_id] = ns

    def answered(self, node: str, t_ns: int) -> bool:
        """Whether ``node`` has answered simulated time ``t_ns`` [ns]."""
        return self.latest.get(node, _NEVER) >= t_ns

    def wait(self, ok: Callable[[], bool], what: Callable[[], str]) -> float:
        """Takes answers until ``ok()``; :class:`Ros2Timeout` with ``what()`` after ``timeout_s`` of wall-clock time.
        Returns the seconds waited."""
        from cyclonedds.core import ReadCondition, SampleState, WaitSet
        from cyclonedds.util import duration

        w0 = time.perf_counter()
        deadline = w0 + self.timeout_s
        if self._waitset is None:
            self._waitset = WaitSet(self._participant)
            self._waitset.attach(ReadCondition(self.reader, SampleState.NotRead))
        self.take()
        while not ok():
            left = deadline - time.perf_counter()
            if left <= 0:
                raise Ros2Timeout(what())
            self._waitset.wait(duration(seconds=min(left, 0.05)))
            self.take()
        return time.perf_counter() - w0
