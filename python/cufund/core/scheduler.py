"""Deterministic event timing and ordering for the simulator's components.

Time is kept in integer nanoseconds. A component with rate f and phase φ runs at
``t_k = t_start + φ + floor(k · 10⁹ / f)`` ns for k = 0, 1, 2, …: each event time is computed from k (never
accumulated), so a rate that does not divide the physics rate neither drifts nor needs rounding beyond 1 ns
(30 Hz runs at 0, 33 333 333, 66 666 666, 100 000 000 ns, …). Rates are taken as the fraction nearest to the
given float with a denominator up to 10⁶ (so 0.1 Hz is exactly 1/10 Hz).

Within one instant components run in topological order of their zero-latency connections (a component that
publishes a topic runs before those that read it); connections with a latency impose no order (the message is
not visible in the instant it is published). Ties keep the order components were added in. A cycle of
zero-latency connections is an error that names it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from fractions import Fraction
from itertools import pairwise
from typing import Any

__all__ = ["EventClock", "ScheduleError", "seconds_to_ns", "topological_order"]

NS = 1_000_000_000


class ScheduleError(ValueError):
    """Components cannot be scheduled: a bad rate, phase or latency, or a cycle of zero-latency connections."""


def seconds_to_ns(name: str, value: Any, allow_zero: bool = True) -> int:
    """``value`` [s] as whole nanoseconds; a ScheduleError naming ``name`` unless finite and >= 0."""
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float))
        or not math.isfinite(value)
        or value < 0
        or (value == 0 and not allow_zero)
    ):
        bound = ">= 0" if allow_zero else "> 0"
        raise ScheduleError(f"{name} must be a finite number {bound} [s], got {value!r}")
    return round(value * NS)


def rate_fraction(name: str, rate_hz: Any) -> Fraction:
    """The rate as an exact fraction [Hz]; a ScheduleError naming ``name`` unless finite and > 0."""
    if isinstance(rate_hz, bool) or not isinstance(rate_hz, (int, float)) or not math.isfinite(rate_hz) or rate_hz <= 0:
        raise ScheduleError(f"{name} must be a finite number > 0 [Hz], got {rate_hz!r}")
    if rate_hz > 1e9:
        raise ScheduleError(f"{name} must be at most 1e9 Hz (one event per nanosecond), got {rate_hz!r}")
    exact = Fraction(rate_hz)
    near = exact.limit_denominator(1_000_000)
    return near if abs(near - exact) <= abs(exact) * Fraction(1, 10**12) else exact


class EventClock:
    """The event times of one periodic activity, in ns from ``start_ns``."""

    __slots__ = ("start_ns", "num", "den", "k", "next_ns")

    def __init__(self, rate: Fraction, phase_ns: int, start_ns: int) -> None:
        self.start_ns = start_ns + phase_ns
        self.num, self.den = rate.numerator, rate.denominator  # period = den / num s
        self.k = 0
        self.next_ns = self.start_ns

    def advance(self) -> int:
        """Moves to the next event; returns its time [ns]."""
        self.k += 1
        self.next_ns = self.start_ns + (self.k * NS * self.den) // self.num
        return self.next_ns

    @property
    def period_ns(self) -> float:
        return NS * self.den / self.num


def topological_order(
    names: Sequence[str], inputs: Sequence[Sequence[str]], outputs: Sequence[Sequence[str]], latencies_ns: Sequence[int]
) -> list[int]:
    """Indices of the components in an order where, within an instant, every zero-latency publisher of a topic
    comes before its readers (ties in the given order). ``inputs`` include optional inputs."""
    n = len(names)
    producers: dict[str, list[int]] = {}
    for i, outs in enumerate(outputs):
        if latencies_ns[i] == 0:
            for topic in outs:
                producers.setdefault(str(topic), []).append(i)
    after: list[set[int]] = [set() for _ in range(n)]  # after[i]: components that must run after i
    edge_topic: dict[tuple[int, int], str] = {}
    for j, ins in enumerate(inputs):
        for topic in ins:
            for i in producers.get(str(topic), ()):
                if i != j:
                    after[i].add(j)
                    edge_topic.setdefault((i, j), str(topic))
    indegree = [0] * n
    for i in range(n):
        for j in after[i]:
            indegree[j] += 1
    order: list[int] = []
    ready = [i for i in range(n) if indegree[i] == 0]
    while ready:
        i = min(ready)  # ties: the order of adding
        ready.remove(i)
        order.append(i)
        for j in sorted(after[i]):
            indegree[j] -= 1
            if indegree[j] == 0:
                ready.append(j)
    if len(order) < n:
        raise ScheduleError("zero-latency cycle: " + _describe_cycle(names, after, edge_topic, set(order)))
    return order


def _describe_cycle(
    names: Sequence[str], after: list[set[int]], edge_topic: dict[tuple[int, int], str], done: set[int]
) -> str:
    """One cycle among the components not in ``done``, as 'a -[/topic]-> b -[/topic]-> a'; give one of them a
    latency to break it."""
    left = [i for i in range(len(names)) if i not in done]
    before = {j: [i for i in left if j in after[i]] for j in left}  # every one left has a predecessor left
    path, seen = [left[0]], {left[0]: 0}
    while True:
        prev = min(before[path[-1]])
        if prev in seen:
            cycle = list(reversed(path[seen[prev] :] + [prev]))
            break
        seen[prev] = len(path)
        path.append(prev)
    parts = [names[cycle[0]]]
    for a, b in pairwise(cycle):
        parts.append(f"-[{edge_topic[(a, b)]}]-> {names[b]}")
    return " ".join(parts) + " (give one of them a latency_s > 0, or remove a connection)"
