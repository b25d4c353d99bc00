"""Leader–follower formation flown in flight: the ``formation_follower`` planner kind (docs/guides/fleets.md).

A follower flies its slot of a formation around a leader that flies its own mission. Its only knowledge of the
leader is the leader's *estimate* (the leader estimator's ``/estimator/odometry``, never its truth), carried to the
follower's bus on :data:`LEADER_ODOMETRY` by the fleet's radio link (:mod:`cufund.missions.formation_link`) at
``comm_rate_hz`` and ``comm_latency_s`` late. At its own rate the follower turns the newest message into a setpoint
(Desai, Ostrowski and Kumar 1998, the l-psi form with fixed l and psi):

    p_ref = p_L + R_z(psi_L) o              o: the slot ``offset`` in the leader's heading frame (FLU) [m]
    v_ref = v_L + psi_dot_L e_z x R_z(psi_L) o
    psi_ref = psi_L

with ``psi_L`` the leader's estimated yaw and ``psi_dot_L`` its estimated yaw rate (world z of its body rate). With
``extrapolate`` the leader's horizontal position is first carried forward by its velocity over the message's age
(constant velocity prediction; not in height, where it would put a follower on the ground ahead of a landing
leader); without (the default), the follower lags a leader flying at v by about v times the message's
age (latency plus, on average, half the broadcast period).

Before the first message the follower publishes nothing (its controller stays idle on the ground). It has flown its
part once the leader's broadcast shows the leader back on the ground (below ``landed_height_m`` and slower than
0.1 m/s after it was above ``airborne_height_m``) and it has landed itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.build_context import BuildContext
from cufund.core.components import BusView, Planner
from cufund.core.config import ConfigError, vector3
from cufund.core.messages import Odometry, Topics, TrajectorySetpoint
from cufund.core.registry import Kind, register
from cufund.core.topics import Topic

__all__ = ["LEADER_ODOMETRY", "FormationFollower", "FormationFollowerParams", "slot_setpoint"]

LEADER_ODOMETRY = Topic("/formation/leader/odometry", Odometry)
"""The leader's estimate as the follower receives it over the link (a copy of the leader's ``/estimator/odometry``
message, visible at the follower ``comm_latency_s`` after it was sent)."""


@dataclass(frozen=True)
class FormationFollowerParams:
    """A follower's slot, its leader and the link that carries the leader's estimate to it."""

    leader: str = ""
    """The leader's vehicle name (in the scenario's ``vehicles``); it must fly on an estimator."""
    offset: tuple[float, float, float] = (-2.0, 0.0, 0.0)
    """The slot in the leader's heading frame, FLU (x forward, y left, z up) [m]
    (``cufund.missions.formation.formation_offsets`` gives the usual shapes)."""
    comm_rate_hz: float = 20.0
    """How often the leader's estimate is sent [Hz] (at the first fleet interaction instant, every 4 ms, at or after
    each send time)."""
    comm_latency_s: float = 0.05
    """How long a message takes to arrive [s] (>= 0)."""
    extrapolate: bool = False
    """Carry the leader's horizontal position forward by its velocity over the message's age (t - stamp)."""
    rate_hz: float | None = None
    """Setpoint rate [Hz]; null: the scenario's trajectory rate."""
    airborne_height_m: float = 0.5
    """The leader counts as having taken off once its estimate is above this height [m]."""
    landed_height_m: float = 0.05
    """... and as landed again once it is below this height [m] (and slower than 0.1 m/s)."""

    def __post_init__(self) -> None:
        if not isinstance(self.leader, str):  # given at build (empty by default, as every kind's params build bare)
            raise ConfigError(f"planner.leader must be a vehicle's name, got {self.leader!r}")
        object.__setattr__(self, "offset", vector3("planner.offset", self.offset, " [m]", finite=True))
        for name, lo in (("comm_rate_hz", 0.0), ("airborne_height_m", 0.0), ("landed_height_m", 0.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= lo:
                raise ConfigError(f"planner.{name} must be a finite number > {lo:g}, got {v!r}")
        v = self.comm_latency_s
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or not 0 <= v <= 10:
            raise ConfigError(f"planner.comm_latency_s must be a time in [0, 10] [s], got {v!r}")
        if self.comm_rate_hz > 1000:
            raise ConfigError(f"planner.comm_rate_hz must be at most 1000 [Hz], got {self.comm_rate_hz!r}")
        if not isinstance(self.extrapolate, bool):
            raise ConfigError(f"planner.extrapolate must be true or false, got {self.extrapolate!r}")
        r = self.rate_hz
        if r is not None and (isinstance(r, bool) or not isinstance(r, (int, float)) or not 0 < r <= 1000):
            raise ConfigError(f"planner.rate_hz must be a rate in (0, 1000] [Hz] or null, got {r!r}")
        if self.landed_height_m >= self.airborne_height_m:
            raise ConfigError("planner.landed_height_m must be below planner.airborne_height_m")


def _yaw(q_WB: np.ndarray) -> float:
    w, x, y, z = (float(c) for c in q_WB)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def slot_setpoint(
    leader: Odometry, offset: np.ndarray, t: float, extrapolate: bool = False
) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The slot's position, velocity [m, m/s, world], yaw and yaw rate [rad, rad/s] at ``t`` [s] from the leader's
    estimate ``leader`` (see the module doc)."""
    psi = _yaw(leader.q_WB)
    c, s = math.cos(psi), math.sin(psi)
    o = np.asarray(offset, dtype=float)
    r_W = np.array([c * o[0] - s * o[1], s * o[0] + c * o[1], o[2]])
    w_B = np.asarray(leader.w_B, dtype=float)
    w, x, y, z = (float(v) for v in leader.q_WB)
    # world z of the body rate: the third row of R_WB times w_B
    psi_dot = float(2 * (x * z - w * y) * w_B[0] + 2 * (y * z + w * x) * w_B[1] + (1 - 2 * (x * x + y * y)) * w_B[2])
    v_L = np.asarray(leader.v_W, dtype=float)
    p_L = np.asarray(leader.p_W, dtype=float)
    if extrapolate:  # horizontally, at constant velocity over the message's age
        age = max(0.0, t - float(leader.t))
        p_L = p_L + age * np.array([v_L[0], v_L[1], 0.0])
    v = v_L + psi_dot * np.array([-r_W[1], r_W[0], 0.0])
    return p_L + r_W, v, psi, psi_dot


class FormationFollower(Planner):
    """Publishes its slot around the leader's newest received estimate as the trajectory setpoint (module doc)."""

    name = "formation_follower"

    def __init__(self, params: FormationFollowerParams, rate_hz: float) -> None:
        self.params = params
        self.rate_hz = float(rate_hz)
        self.optional_reads = (LEADER_ODOMETRY,)
        self.writes = (Topics.TRAJECTORY_SETPOINT,)
        self._offset = np.asarray(params.offset, dtype=float)
        self.reset()

    def reset(self) -> None:
        self.leader_airborne = False
        """The leader's estimate has been above ``airborne_height_m``."""
        self.leader_landed = False
        """... and has come back below ``landed_height_m``, slow."""
        self.messages_used = 0

    def update(self, t: float, state: Odometry, bus: BusView) -> None:
        msg: Odometry | None = bus.latest(LEADER_ODOMETRY)
        if msg is None:
            return
        p = self.params
        z = float(msg.p_W[2])
        if z > p.airborne_height_m:
            self.leader_airborne = True
        elif self.leader_airborne and z < p.landed_height_m and float(np.linalg.norm(msg.v_W)) < 0.1:
            self.leader_landed = True
        pos, vel, yaw, yaw_rate = slot_setpoint(msg, self._offset, t, p.extrapolate)
        self.messages_used += 1
        zero = np.zeros(3)
        bus.publish(Topics.TRAJECTORY_SETPOINT, TrajectorySetpoint(t, pos, vel, zero, zero, yaw, yaw_rate))


def _formation_follower(p: FormationFollowerParams, ctx: BuildContext) -> list[Any]:
    cfg = ctx.config
    if not p.leader:
        raise ConfigError("planner.leader must name the leader vehicle (a vehicle of the scenario's vehicles)")
    if cfg.estimator is None:
        raise ConfigError(
            "planner (formation_follower): the follower needs an estimator (estimator:); it flies on its own estimate"
        )
    follower = FormationFollower(p, p.rate_hz if p.rate_hz is not None else cfg.rates.trajectory_hz)

    def done(t: float, truth: Any) -> bool:  # a harness check: the leader is down (as heard) and so is the follower
        return follower.leader_landed and float(truth.p_W[2]) < 0.02 and float(np.linalg.norm(truth.v_W)) < 0.05

    ctx.set_done_condition(done)
    return [follower]


register(
    Kind(
        "planner",
        "formation_follower",
        FormationFollowerParams,
        _formation_follower,
        None,
        "fly a slot of a leader-follower formation around the leader's estimate, received over a delayed link",
    )
)
