"""Is the state estimate healthy? The one monitor of the estimator's health that the failsafe supervisor acts on
and the tunnel mission waits on (it held its own copy before): the LIO reports each LiDAR frame on
``Topics.ESTIMATOR_DIAGNOSTICS`` (``healthy``, ``reason``); no report for ``silence_s`` is unhealthy too. Unhealthy
spells are recorded as ``(start [s], length [s], reason)``. Reads flight data only."""

from __future__ import annotations

from typing import Any

from cufund.core.messages import Topics

__all__ = ["EstimatorHealth"]


class EstimatorHealth:
    """``setup(bus)`` once in the owner's setup; ``update(t)`` from any number of components at the same instant
    (evaluated once per ``t``) returns ``(healthy, reason)``."""

    def __init__(self, silence_s: float = 0.35) -> None:
        self.silence_s = float(silence_s)
        self._diagnostics: Any = None
        self.reset()

    def reset(self) -> None:
        self.events: list[tuple[float, float, str]] = []
        """Spells of an unhealthy estimator: (start [s], length [s], reason)."""
        self.t_unhealthy: float | None = None
        """When the current unhealthy spell began [s] (None while healthy)."""
        self._diag_t: float | None = None
        self._diag_ok, self._diag_reason = True, ""
        self._last: tuple[float, bool, str] | None = None

    def setup(self, bus: Any) -> None:
        self.reset()
        self._diagnostics = bus.subscribe(Topics.ESTIMATOR_DIAGNOSTICS)

    @property
    def reporting(self) -> bool:
        """Whether the estimator has reported a LiDAR frame yet (before that there is nothing to judge)."""
        return self._diag_t is not None

    def update(self, t: float) -> tuple[bool, str]:
        """Is the estimator healthy at ``t`` (its newest report recent and marked healthy)? Records the spells."""
        if self._last is not None and self._last[0] == t:
            return self._last[1], self._last[2]
        if self._diagnostics is not None:
            for d in self._diagnostics.take():
                self._diag_t = float(d.t)
                self._diag_ok, self._diag_reason = bool(getattr(d, "healthy", True)), str(getattr(d, "reason", ""))
        if self._diag_t is None:  # no LiDAR frame processed yet (initialising): nothing to judge
            ok, why = True, ""
        elif t - self._diag_t > self.silence_s:
            ok, why = False, f"no LiDAR frame for {t - self._diag_t:.2f} s"
        else:
            ok, why = self._diag_ok, self._diag_reason
        if not ok and self.t_unhealthy is None:
            self.t_unhealthy = t
            self.events.append((t, 0.0, why or "unhealthy"))
        elif ok and self.t_unhealthy is not None:
            t0, _, r = self.events[-1]
            self.events[-1] = (t0, t - t0, r)
            self.t_unhealthy = None
        elif not ok and self.events:
            t0, _, r = self.events[-1]
            self.events[-1] = (t0, t - t0, r)
        self._last = (t, ok, why)
        return ok, why
