"""Replaying a log into a simulator: the bag-driven workflow of LiDAR-odometry developers, without ROS."""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path

from cufund.core.bus import BusView
from cufund.core.components import Component
from cufund.core.topics import Topic, is_truth

from .mcap_reader import LogRecord, log_topics, read_mcap
from .rosbag2_reader import bag_topics, is_rosbag2, read_rosbag2

__all__ = ["LogPlayer"]


class LogPlayer(Component):
    """Publishes the messages of a cufund MCAP log (``run.mcap``) or of a ROS 2 bag folder (its IMU, LiDAR and
    odometry messages as cufund messages, :mod:`cufund.logs.rosbag2_reader`) on their topics, each becoming
    visible at the time it became visible in the recorded run, so that an estimator or mapper re-run on the log
    sees exactly what it saw closed-loop (run it in a ``Simulator(None)``: no physics).

    ``topics``: which logged topics to play (default: every ``/sensors/...`` topic; of a bag, every IMU and LiDAR
    topic). A mapping ``{logged topic: topic to publish it on}`` renames (a bag's ``/imu`` onto ``/sensors/imu``,
    where cufund's estimators read). Truth topics are played only when named, and the player then counts as a
    truth consumer. The log is streamed: the player schedules the next ``window_s`` of messages each time it runs,
    so memory stays bounded however long the log.
    """

    name = "log_player"

    def __init__(
        self,
        path: str | os.PathLike[str],
        topics: Iterable[str] | Mapping[str, str] | None = None,
        window_s: float = 0.5,
    ) -> None:
        self.path = Path(path)
        bag = is_rosbag2(self.path)
        self._read = read_rosbag2 if bag else read_mcap
        logged = bag_topics(self.path) if bag else log_topics(self.path)  # McapReadError / BagReadError: damaged
        if topics is None and bag:
            chosen = [t for t, c in logged.items() if c in ("Imu", "PointCloud")]
        elif topics is None:
            chosen = [t for t in logged if t.startswith("/sensors/")]
        else:
            chosen = [str(t) for t in topics]  # a mapping: its keys
            missing = [t for t in chosen if t not in logged]
            if missing:
                raise ValueError(f"topics: {missing[0]} is not in {self.path} (it has {', '.join(sorted(logged))})")
        if not window_s > 0:
            raise ValueError(f"window_s must be > 0 [s], got {window_s!r}")
        from cufund.core import messages

        self._logged = tuple(chosen)
        self._renamed = {t: str(topics[t]) for t in chosen} if isinstance(topics, Mapping) else {t: t for t in chosen}
        self.topics = tuple(Topic(self._renamed[t], getattr(messages, logged[t], object)) for t in chosen)
        self.outputs = self.topics
        self.reads_truth = any(is_truth(t) or is_truth(self._renamed[t]) for t in chosen)  # type: ignore[misc]
        self.rate_hz = 1.0 / window_s
        self.window_ns = round(window_s * 1e9)
        self.played = 0
        """Messages scheduled so far."""

    def reset(self) -> None:
        self._records: Iterator[LogRecord] = self._read(self.path, topics=list(self._logged))
        self._next: LogRecord | None = None
        self.played = 0

    def setup(self, bus: BusView) -> None:
        self._schedule(bus)  # before the first instant's messages are released

    def step(self, t: float, bus: BusView) -> None:
        self._schedule(bus)

    def _schedule(self, bus: BusView) -> None:
        """Schedules the logged messages up to two windows ahead of now (ahead of the next run)."""
        now = bus._bus.now_ns
        horizon = now + 2 * self.window_ns
        while True:
            if self._next is None:
                self._next = next(self._records, None)
                if self._next is None:
                    return
            rec = self._next
            if rec.log_time_ns > horizon:
                return
            if rec.log_time_ns >= now:  # what lies before the start is not played
                bus.publish_at(self._renamed[rec.topic], rec.message, rec.log_time_ns, rec.publish_time_ns)
                self.played += 1
            self._next = None

    @property
    def first_time(self) -> float:
        """The log time of the first message played [s] (start the simulator there)."""
        first = next(self._read(self.path, topics=list(self._logged)), None)
        return 0.0 if first is None else first.log_time_ns / 1e9
