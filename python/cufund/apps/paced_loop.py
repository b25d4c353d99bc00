"""The wall-clock pacing of a live run: a simulation advanced in a background thread at ``speed`` x real time (or as
fast as it goes), paused, resumed, re-paced and stopped from any thread. :class:`cufund.apps.live.LiveRun` (one
vehicle) and :class:`cufund.apps.mavlink.fleet_live.LiveFleet` (every vehicle of a fleet, advanced together) are
both one; what they advance and what they do after each advance are theirs (the hooks below).

The loop advances in steps of at most 50 ms of simulated time. Behind the wall clock by more than 0.5 s of
simulated time, it does not try to catch up: it goes on from where it is (a slow machine runs slower than asked,
it never bursts). Ahead of it, it sleeps on a condition that a new command, a pause or a new speed wakes.
"""

from __future__ import annotations

import collections
import math
import threading
import time
from typing import Any, Self

__all__ = ["SPEED_MAX", "SPEED_MIN", "PacedLoop", "check_speed"]

SPEED_MIN, SPEED_MAX = 0.1, 10.0
"""The pace a live run takes [simulated s per wall s], besides ``math.inf``."""
_STEP_S = 0.05
"""Longest advance of one pass of the loop [s of simulated time]."""
_MAX_LAG_S = 0.5
"""Simulated time behind the wall clock past which the loop stops trying to catch up [s]."""


def check_speed(x: Any) -> float:
    """``x`` as a pace: a number in [SPEED_MIN, SPEED_MAX] or ``math.inf``; ValueError naming it otherwise."""
    if (
        isinstance(x, bool)
        or not isinstance(x, (int, float))
        or math.isnan(x)
        or not (x == math.inf or SPEED_MIN <= x <= SPEED_MAX)
    ):
        raise ValueError(f"speed must be in [{SPEED_MIN}, {SPEED_MAX}] or math.inf, got {x!r}")
    return float(x)


class PacedLoop:
    """Pacing, pausing and stopping of a simulation thread. A subclass calls :meth:`_init_pacing` and provides:

    - ``_sim_t()``: the simulation's time [s];
    - ``_advance_to(t)``: advances it to ``t``; False once the run has ended;
    - ``_after_advance()``: what follows each advance before listeners hear of it (snapshots, trimming);
    - ``_notify_listeners()``: tells its listeners;
    - ``_while_paused(t)``: what is done on each pass while paused (answering commands);
    - ``_end_of_run()``: (why, event kind) of a run whose ``_advance_to`` returned False;
    - ``_end(why, kind)``: records the end;
    - ``_cancel_pending(why)``: fails the commands still queued.
    """

    _thread_name = "cufund-live"

    def _init_pacing(self, speed: float) -> None:
        self._speed = check_speed(speed)
        self._paused = False
        self._stop = threading.Event()
        self._wake = threading.Condition()
        self._thread: threading.Thread | None = None
        self._rate_window: collections.deque[tuple[float, float]] = collections.deque(maxlen=400)
        self.ended: str | None = None
        """Why the run ended (None while it runs)."""

    # -- hooks ---------------------------------------------------------------------------------------------------
    def _sim_t(self) -> float:
        raise NotImplementedError

    def _advance_to(self, t: float) -> bool:
        raise NotImplementedError

    def _after_advance(self) -> None:
        pass

    def _notify_listeners(self) -> None:
        pass

    def _while_paused(self, t: float) -> None:
        pass

    def _end_of_run(self) -> tuple[str, str]:
        return "ended", "ended"

    def _end(self, why: str, kind: str) -> None:
        self.ended = why

    def _cancel_pending(self, why: str) -> None:
        pass

    # -- control -------------------------------------------------------------------------------------------------
    def start(self) -> Self:
        if self._thread is None:
            self._thread = threading.Thread(target=self._loop, name=self._thread_name, daemon=True)
            self._thread.start()
        return self

    def pause(self) -> None:
        with self._wake:
            self._paused = True
            self._wake.notify_all()

    def resume(self) -> None:
        with self._wake:
            self._paused = False
            self._wake.notify_all()

    @property
    def paused(self) -> bool:
        return self._paused

    @property
    def speed(self) -> float:
        return self._speed

    def set_speed(self, x: float) -> None:
        """Simulated seconds per wall-clock second: 0.1 to 10, or ``math.inf`` (as fast as possible)."""
        x = check_speed(x)
        with self._wake:
            self._speed = x
            self._wake.notify_all()

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def stop(self, timeout: float = 10.0) -> None:
        """Ends the run and joins the simulation thread; queued commands fail."""
        self._stop.set()
        with self._wake:
            self._wake.notify_all()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout)
        if self.ended is None:
            self.ended = "stopped"
        self._cancel_pending("the run has ended")

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def real_time_factor(self) -> float | None:
        """Simulated seconds per wall second over the last ~2 s (None while paused or before two passes)."""
        window = list(self._rate_window)
        if len(window) >= 2 and window[-1][0] > window[0][0] and not self._paused:
            return (window[-1][1] - window[0][1]) / (window[-1][0] - window[0][0])
        return None

    # -- the simulation thread -----------------------------------------------------------------------------------
    def _loop(self) -> None:
        try:
            wall0, sim0 = time.perf_counter(), self._sim_t()
            speed = self._speed
            while not self._stop.is_set():
                with self._wake:
                    if self._paused:
                        self._wake.wait(0.05)
                        wall0, sim0 = time.perf_counter(), self._sim_t()
                        self._while_paused(sim0)  # commands are answered while paused, applied at this time
                        continue
                    if self._speed != speed:
                        speed, wall0, sim0 = self._speed, time.perf_counter(), self._sim_t()
                t = self._sim_t()
                if speed == math.inf:
                    target = t + _STEP_S
                else:
                    target = sim0 + (time.perf_counter() - wall0) * speed
                    if target - t > _MAX_LAG_S:  # cannot keep up: do not try to catch up, go on from here
                        wall0, sim0 = time.perf_counter() - _STEP_S / speed, t
                        target = t + _STEP_S
                    target = min(target, t + _STEP_S)
                    if target - t < 0.001:
                        with self._wake:
                            self._wake.wait(min(0.005, max(0.001, (0.002 - (target - t)) / speed)))
                        continue
                alive = self._advance_to(target)
                self._after_advance()
                now = time.perf_counter()
                window = self._rate_window
                window.append((now, self._sim_t()))
                while len(window) > 2 and now - window[0][0] > 2.0:
                    window.popleft()
                self._notify_listeners()
                if not alive:
                    self._end(*self._end_of_run())
                    break
        except Exception as e:
            self._end(f"error: {type(e).__name__}: {e}", "error")
        finally:
            if self.ended is None:
                self.ended = "stopped"
            self._cancel_pending(f"the run has ended ({self.ended})")
