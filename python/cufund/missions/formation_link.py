"""The radio link of a leader–follower formation and its formation-error metrics (docs/guides/fleets.md).

:func:`connect_formation_links` is called on every built fleet (``cufund.scenarios.fleet.build_fleet``): for each
follower (a vehicle whose planner is a :class:`~cufund.missions.formation_follower.FormationFollower`) it adds a
:class:`FormationLink` to the fleet's interaction observers. At the fleet's interaction instants (every 4 ms) the
link:

* every ``1 / comm_rate_hz`` takes the leader's newest estimate from the leader's bus, reading it through a bus view
  whose only input is ``/estimator/odometry`` and that refuses ``/truth/`` topics (the link cannot carry the truth),
  and publishes it on the follower's bus on :data:`~cufund.missions.formation_follower.LEADER_ODOMETRY`, visible
  ``comm_latency_s`` after the send instant;
* records the leader's and the follower's true poses for the metrics (harness side: the follower never sees them).

The follower's ``metrics.json`` block then gains ``formation_error_rmse_m`` and ``formation_error_max_m``: the
distance of the follower's true position from its slot around the leader's *true* pose (``p_L + R_z(psi_L) o``),
over the instants at which the leader is truly above ``airborne_height_m`` (the formation's flight); also the mean
along-track (the leader's heading, + ahead) and cross-track (+ left) parts and the messages sent.
"""

from __future__ import annotations

import math
from array import array
from typing import Any

import numpy as np

from cufund.core.bus import BusView
from cufund.core.config import ConfigError
from cufund.core.messages import Topics
from cufund.core.scheduler import NS

from .formation_follower import LEADER_ODOMETRY, FormationFollower

__all__ = ["FormationLink", "connect_formation_links", "formation_errors"]


def _yaw(q: np.ndarray) -> np.ndarray:
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def formation_errors(
    p_L: np.ndarray, q_L: np.ndarray, p_F: np.ndarray, offset: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The follower's error from its slot (K, 3) [m, world], its along-track and cross-track parts (K,) [m], from
    the poses (K, 3) / (K, 4 [w, x, y, z]) of the leader and the follower's positions (K, 3)."""
    psi = _yaw(np.asarray(q_L, dtype=float))
    c, s = np.cos(psi), np.sin(psi)
    o = np.asarray(offset, dtype=float)
    slot = np.asarray(p_L, dtype=float) + np.stack([c * o[0] - s * o[1], s * o[0] + c * o[1], np.full_like(c, o[2])], 1)
    e = np.asarray(p_F, dtype=float) - slot
    return e, c * e[:, 0] + s * e[:, 1], -s * e[:, 0] + c * e[:, 1]


class FormationLink:
    """Carries the leader's estimate to one follower and records both true poses (see the module doc)."""

    def __init__(self, fleet: Any, follower: str, component: FormationFollower) -> None:
        p = component.params
        if p.leader == follower:
            raise ConfigError(f"vehicles.{follower}.planner.leader must be another vehicle, not the follower itself")
        try:
            leader = fleet.vehicle(p.leader)
        except KeyError:
            raise ConfigError(
                f"vehicles.{follower}.planner.leader {p.leader!r} is not a vehicle of the fleet "
                f"({', '.join(fleet.names)})"
            ) from None
        if leader.config.estimator is None:
            raise ConfigError(
                f"vehicles.{follower}.planner.leader {p.leader!r} has no estimator: a follower tracks the leader's "
                "estimate (its /estimator/odometry), never its truth"
            )
        self.leader_name, self.follower_name = p.leader, follower
        self.params = p
        self._leader, self._follower = leader, fleet.vehicle(follower)
        self._period_ns = max(1, round(NS / p.comm_rate_hz))
        self._latency_ns = round(p.comm_latency_s * NS)
        self._buses: tuple[Any, Any] | None = None
        self.view: BusView | None = None
        self.sent = 0
        self._rows = array("d")
        """11 doubles per interaction instant: t, the leader's true p (3) and q (4), the follower's true p (3)."""
        self.keep_rows: int | None = None
        """Keep only about the newest ``keep_rows`` instants (between 1 and 2 times as many); None: all, as a run's
        metrics need. A live fleet sets it: it may fly for hours (88 bytes an instant, 80 MB an hour at 250 Hz)."""

    def __call__(self, t: float) -> None:
        lb, fb = self._leader.bus, self._follower.bus
        if lb is None or fb is None:
            return
        now = round(t * NS)
        if self._buses is None or self._buses[0] is not lb or self._buses[1] is not fb:  # a new run
            self._buses = (lb, fb)
            self.view = BusView(lb, f"formation_link:{self.follower_name}", [Topics.ESTIMATE], [], deny_truth=True)
            self._next_ns = now
            self.sent = 0
            self._rows = array("d")
        if now >= self._next_ns:
            msg = self.view.latest(Topics.ESTIMATE)  # type: ignore[union-attr]
            if msg is not None:
                fb.publish(LEADER_ODOMETRY, msg, now + self._latency_ns - fb.now_ns)
                self.sent += 1
            while self._next_ns <= now:
                self._next_ns += self._period_ns
        ls, fs = self._leader.simulator.vehicle.state, self._follower.simulator.vehicle.state  # harness: metrics
        self._rows.append(t)
        self._rows.extend(ls.p)
        self._rows.extend(ls.q)
        self._rows.extend(fs.p)
        keep = self.keep_rows
        if keep is not None and len(self._rows) > 22 * keep:  # drop the older half at once: amortised O(1)
            del self._rows[: len(self._rows) - 11 * keep]

    def metrics(self, result: Any = None) -> dict[str, Any]:
        """The follower's formation figures (see the module doc)."""
        out: dict[str, Any] = {
            "formation_leader": self.leader_name,
            "formation_messages_sent": self.sent,
            "formation_error_rmse_m": None,
            "formation_error_max_m": None,
            "formation_error_along_mean_m": None,
            "formation_error_cross_mean_m": None,
        }
        s = self.samples()
        if not len(s["t"]):
            return out
        p_L, q_L, p_F = s["p_L"], s["q_L"], s["p_F"]
        flying = p_L[:, 2] > self.params.airborne_height_m
        if not flying.any():
            return out
        e, along, cross = formation_errors(p_L[flying], q_L[flying], p_F[flying], np.asarray(self.params.offset))
        d = np.linalg.norm(e, axis=1)
        out.update(
            formation_error_rmse_m=float(math.sqrt(np.mean(d * d))),
            formation_error_max_m=float(d.max()),
            formation_error_along_mean_m=float(along.mean()),
            formation_error_cross_mean_m=float(cross.mean()),
        )
        return out

    def samples(self) -> dict[str, np.ndarray]:
        """The recorded instants: ``t`` (K,) [s], ``p_L``, ``q_L``, ``p_F`` (K, 3 or 4), truth (for tests, plots)."""
        rows = np.frombuffer(self._rows, dtype=float).reshape(-1, 11).copy()
        return {"t": rows[:, 0], "p_L": rows[:, 1:4], "q_L": rows[:, 4:8], "p_F": rows[:, 8:11]}


def connect_formation_links(fleet: Any) -> Any:
    """Adds a :class:`FormationLink` to ``fleet``'s observers for each follower of a built fleet (and its metrics
    to the follower's run); returns ``fleet``. ``fleet.formation_links`` lists them by follower name."""
    links: dict[str, FormationLink] = {}
    for name in fleet.names:
        vehicle = fleet.vehicle(name)
        for c in vehicle.simulator.components:
            if isinstance(c, FormationFollower):
                link = FormationLink(fleet, name, c)
                fleet.simulator.observers.append(link)
                vehicle.built.context.add_metric_hook(link.metrics)
                links[name] = link
    fleet.formation_links = links
    return fleet
