"""Several vehicles in one world: one lockstep :class:`~cufund.simulator.Simulator` per vehicle (its own bus, its
own components, its own event schedule), advanced together, with what couples them applied between steps.

Every ``1 / interaction_rate_hz`` of simulated time (default 250 Hz, the single-vehicle collision check's rate)
the fleet advances each vehicle's simulator to that instant (:meth:`Simulator.advance_to`, which never splits a
physics step for where a call ends: a vehicle's run is the same, bit for bit, whatever the fleet's grid), then:

* checks every pair of vehicles closer than their boxes' half-diagonals for contact through Bullet
  (:class:`cufund.worlds.collision.CollisionChecker`, the same check a vehicle has against the world): a contact
  ends the fleet's run, both vehicles CRASHED, the message naming both;
* records the closest centre-to-centre distance of any two vehicles (``fleet_min_separation_m``);
* sets the rotor downwash of each vehicle on the others (:mod:`cufund.worlds.downwash`, when the scenario asks for
  it) as an external force on their plants, held until the next instant;
* every ``1 / view_rate_hz`` (default 50 Hz) remakes the world each vehicle's ray-cast sensors see: the world with
  the other vehicles' boxes at their current poses (:class:`~cufund.simulator.fleet_view.WorldWithVehicles`), for
  each vehicle with another within its sensors' reach (:attr:`FleetMember.view_range_m`, else ``view_range_m``)
  plus the other's box; a vehicle with none in range keeps the world itself.

A vehicle with no other within reach (none closer than ``view_range_m`` nor under another's jet) therefore runs
exactly as it runs alone.

**Batched physics** (``batched_physics=True``, the default). Each simulator steps its plant on its own physics grid,
split at its own events (a component's run, a message becoming visible), so two vehicles' steps need not coincide;
stepping every vehicle over the union of all their step boundaries would change each one's arithmetic (two RK4
steps where alone it takes one) and lose the bit-for-bit equality with its single run. So the fleet advances its
vehicles in rounds: in a round each vehicle whose run is open and whose next step ends at or before the fleet's next
instant runs its events and node checks and hands out its next step, (dt, rotor-speed command), exactly the step it
takes alone (``Simulator._advance(..., defer=recorder)``: the simulator hands its step to the fleet),
and one C++ call (``cufund._core.dynamics.step_batches``, the GIL released) integrates all the steps of the round,
each vehicle by its own ``QuadrotorBatch.step(dt, cmd, 1)``: the same arithmetic, bit for bit. Vehicles with the same
schedule (one scenario's stack) step together in every round; others take their own steps in the rounds they need.
Nothing couples the vehicles between two interaction instants, so the order of the rounds changes nothing. A plant
that steps through Python (a wind *function*, a surface probe) takes its step inside its round, alone.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cufund import _core
from cufund.core.messages import Odometry
from cufund.core.scheduler import NS
from cufund.geometry import quat_to_matrix
from cufund.worlds.collision import CollisionChecker
from cufund.worlds.downwash import DownwashConfig, downwash_force, jet_reach
from cufund.worlds.world import World

from .fleet_view import VehicleBox, WorldWithVehicles, box_mesh_W
from .lockstep import RunStatus, SimulationResult, Simulator

__all__ = ["FleetCollision", "FleetMember", "FleetSimulator", "namespaced"]

_SEVERITY = {
    RunStatus.COMPLETED: 0,
    RunStatus.TIMEOUT: 1,
    RunStatus.ABORTED: 2,
    RunStatus.DIVERGED: 3,
    RunStatus.CRASHED: 4,
}


def namespaced(name: str, topic: str) -> str:
    """A vehicle's topic in the fleet's namespace: ``namespaced("uav1", "/sensors/imu") == "/uav1/sensors/imu"``."""
    return f"/{name}{topic}"


@dataclass
class FleetMember:
    """One vehicle of a fleet: its simulator (its plant is ``simulator.vehicle``), its end condition, its shape,
    its propeller radius and the components whose ``world`` is the fleet's (its LiDARs and cameras)."""

    name: str
    simulator: Simulator
    done: Callable[[float, Odometry], bool] | None = None
    box_size: tuple[float, float, float] = (0.216, 0.216, 0.095)
    rotor_radius_m: float = 0.038
    viewers: list[Any] = field(default_factory=list)
    """Components with a ``world`` attribute the fleet points at the world with the others in it."""
    world: World | None = None
    """The world its viewers see when no other vehicle is in range (its own copy of the fleet's world)."""
    view_range_m: float | None = None
    """How far its viewers see [m] (e.g. its LiDAR's range_max): others farther away are left out of its view;
    None: the fleet's ``view_range_m``."""


@dataclass(frozen=True)
class FleetCollision:
    """Two vehicles touching."""

    t: float
    a: str
    b: str
    point_W: tuple[float, float, float]
    depth_m: float


class FleetSimulator:
    """Advances ``members`` together in ``world`` (see the module's docstring)."""

    def __init__(
        self,
        members: Sequence[FleetMember],
        world: World | None = None,
        downwash: DownwashConfig | None = None,
        interaction_rate_hz: float = 250.0,
        view_rate_hz: float = 50.0,
        view_range_m: float = 50.0,
        batched_physics: bool = True,
    ) -> None:
        if not members:
            raise ValueError("a fleet needs at least one vehicle")
        names = [m.name for m in members]
        if len(set(names)) != len(names):
            raise ValueError(f"vehicle names must differ, got {names}")
        for m in members:
            if m.simulator.vehicle is None:
                raise ValueError(f"vehicle {m.name}: its simulator has no plant")
        for name, v in (("interaction_rate_hz", interaction_rate_hz), ("view_rate_hz", view_rate_hz)):
            if not (isinstance(v, (int, float)) and math.isfinite(v) and 0 < v <= 1e4):
                raise ValueError(f"{name} must be a rate in (0, 1e4] [Hz], got {v!r}")
        if not (isinstance(view_range_m, (int, float)) and view_range_m >= 0):
            raise ValueError(f"view_range_m must be a distance >= 0 [m], got {view_range_m!r}")
        self.members = list(members)
        self.names = tuple(names)
        self.world = world
        self.downwash = downwash
        self.step_ns = max(1, round(NS / interaction_rate_hz))
        self.view_every = max(1, round(interaction_rate_hz / view_rate_hz))
        self.view_range_m = float(view_range_m)
        self._boxes = [VehicleBox(m.name, m.box_size) for m in self.members]
        self._rotors_B = [m.simulator.vehicle.params.rotor_positions() for m in self.members]  # type: ignore[union-attr]
        self._radii = np.array([m.rotor_radius_m for m in self.members])
        self._span = np.array([np.max(np.linalg.norm(r, axis=1)) for r in self._rotors_B]) + self._radii + 0.01
        """How far each vehicle's rotor discs reach from its centre [m] (with 1 cm to spare)."""
        self._k_f = np.array([m.simulator.vehicle.params.k_f for m in self.members])  # type: ignore[union-attr]
        self._box_radii = np.array([b.radius for b in self._boxes])
        self._pairs = np.triu_indices(len(self.members), 1)  # (i, j) of every pair i < j
        self._box_vertices_B = np.array([b.vertices_B for b in self._boxes])  # (n, 8, 3)
        box_triangles = self._boxes[0].triangles  # every box has the same 12 triangles over its 8 corners
        self._view_triangles = (box_triangles[None] + 8 * np.arange(len(self._boxes))[:, None, None]).reshape(-1, 3)
        """The triangles of n boxes' corners listed one box after another (a view of k boxes: the first 12 k)."""
        if not isinstance(batched_physics, bool):
            raise ValueError(f"batched_physics must be True or False, got {batched_physics!r}")
        self.batched_physics = batched_physics
        """All vehicles' physics steps in one C++ call per round (see the module's docstring); False: each
        simulator steps its own plant (the same numbers, one call per vehicle-step)."""
        self.physics_seconds = 0.0
        """Wall time in the batched physics calls [s]."""
        self.observers: list[Callable[[float], None]] = []
        """Called with the fleet's time at each interaction instant (e.g. a log's ``/clock``)."""
        self._started = False

    # -- the run -----------------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Starts a run of every vehicle from its plant's current state (each simulator's :meth:`reset`), without
        the downwash the last run left on the plants."""
        for m, force in zip(self.members, getattr(self, "_forces", ()), strict=False):
            if force.any():
                m.simulator.vehicle.force_ext_W[:] -= force  # type: ignore[union-attr]
        for m in self.members:
            m.simulator.reset()
        t0 = {m.simulator.t_start_ns for m in self.members}
        if len(t0) != 1:
            raise ValueError("the vehicles' simulators start at different times; set their plants' time alike")
        self.t_start_ns = self._now_ns = t0.pop()
        self._k = 0
        self.status: RunStatus | None = None
        self.message = ""
        self.collisions: list[FleetCollision] = []
        self.min_separation_m = math.inf
        self.min_separation_at: tuple[float, str, str] | None = None
        self._forces = np.zeros((len(self.members), 3))
        self._wall = 0.0
        self.physics_seconds = 0.0
        self._steps: list[tuple[Any, float, Any, int]] = []
        """The round's recorded steps: (the plant's C++ batch, dt [s], rotor-speed command, vehicle index)."""
        self._recorders: list[Callable[[float, Any], None]] = []
        self._started = True
        self._interact(self._now_ns)

    @property
    def t(self) -> float:
        """The fleet's time [s] (each vehicle's simulator is at it, or at its last physics node or event before)."""
        if not self._started:
            return self.members[0].simulator.t
        return self._now_ns / NS

    @property
    def finished(self) -> bool:
        return self._started and self.status is not None

    def advance_to(self, t: float) -> bool:
        """Simulates every vehicle up to time ``t`` [s] (starting a run if none is open). Returns False once the
        fleet's run has ended (a vehicle-vehicle collision, or every vehicle's own run over)."""
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not math.isfinite(t):
            raise ValueError(f"t must be a finite time [s], got {t!r}")
        if not self._started:
            self.reset()
        if self.status is not None:
            return False
        end_ns = round(t * NS)
        if end_ns < self._now_ns:
            raise ValueError(f"t must not be before the fleet's time {self.t:.9f} s, got {t!r}")
        wall0 = time.perf_counter()
        try:
            while self._now_ns < end_ns and self.status is None:
                grid = self.t_start_ns + (self._k + 1) * self.step_ns
                target = min(grid, end_ns)
                if self.batched_physics:
                    self._advance_batched(target)
                else:
                    for m in self.members:
                        sim = m.simulator
                        if sim.status is None:
                            sim.advance_to(target / NS, m.done)
                self._now_ns = target
                if target == grid:
                    self._k += 1
                    self._interact(target)
                if all(m.simulator.status is not None for m in self.members) and self.status is None:
                    self.status, self.message = self._worst()
        finally:
            wall = time.perf_counter() - wall0
            self._wall += wall
            if self.batched_physics:  # the simulators ran inside the fleet's rounds: each took the fleet's time
                for m in self.members:
                    m.simulator._wall += wall
        return self.status is None

    def _advance_batched(self, end_ns: int) -> None:
        """Every open vehicle up to ``end_ns`` (as its ``advance_to`` would take it there), in rounds of one physics
        step each, each round's steps in one ``step_batches`` call (see the module's docstring)."""
        steps = self._steps
        recorders = self._recorders
        if not recorders:
            record = steps.append

            def recorder(i: int, core: Any) -> Callable[[float, Any], None]:
                def step(dt: float, cmd: Any) -> None:  # the step the simulator hands out instead of taking it
                    record((core, dt, cmd, i))

                return step

            recorders = self._recorders = [
                recorder(i, m.simulator.vehicle._batch._core)  # type: ignore[union-attr]
                for i, m in enumerate(self.members)
            ]
        sims = [m.simulator for m in self.members]
        done = [m.done for m in self.members]
        pending = [i for i, sim in enumerate(sims) if sim.status is None and sim._now_ns < end_ns]
        while pending:
            steps.clear()
            moved = []
            try:
                for i in pending:
                    sim = sims[i]
                    now = sim._now_ns
                    # its events and node checks, then its next step recorded (or taken, a plant stepped through
                    # Python: a wind function, a probe)
                    sim._advance(end_ns, done[i], False, recorders[i])
                    if sim._now_ns != now:  # it took a step (recorded, or its own)
                        moved.append(i)
            finally:
                if steps:
                    self._step_all(steps)
            pending = [i for i in moved if sims[i].status is None and sims[i]._now_ns < end_ns]

    def _step_all(self, steps: list[tuple[Any, float, Any, int]]) -> None:
        """One C++ call integrating the round's recorded steps (plants stepped through Python are already done)."""
        w0 = time.perf_counter()
        try:
            _core.dynamics.step_batches(
                [s[0] for s in steps], np.array([s[1] for s in steps]), np.array([s[2] for s in steps]), 1
            )
        except ValueError as e:  # name the vehicle, as its own simulator's step would have raised it
            match = re.match(r"batches\[(\d+)\]: (.*)", str(e), re.S)
            if match is None:
                raise
            name = self.names[steps[int(match.group(1))][3]]
            raise ValueError(f"vehicle {name}: {match.group(2)}") from None
        finally:
            self.physics_seconds += time.perf_counter() - w0

    def run(self, duration: float) -> dict[str, SimulationResult]:
        """A new run of ``duration`` [s] (or until it ends); each vehicle's result by name. A vehicle whose own
        run is still open at the end gets what a single run gets: its last node checked, then COMPLETED (no end
        condition) or TIMEOUT."""
        if isinstance(duration, bool) or not isinstance(duration, (int, float)) or not duration > 0:
            raise ValueError(f"duration must be a finite number > 0 [s], got {duration!r}")
        if not math.isfinite(duration):
            raise ValueError(f"duration must be a finite number > 0 [s], got {duration!r}")
        self.reset()
        self.advance_to(self.t_start_ns / NS + duration)
        for m in self.members:
            self._close(m)
        if self.status is None:
            self.status, self.message = self._worst()
        return self.results()

    def _close(self, m: FleetMember) -> None:
        """What :meth:`Simulator.run` does after its last ``advance_to``."""
        sim = m.simulator
        if sim.status is None and sim._at_node and sim.vehicle is not None:
            sim._node_checks(sim._now_ns, m.done)  # the last node: recorded, checked
        if sim.status is None:
            sim.status = RunStatus.COMPLETED if m.done is None else RunStatus.TIMEOUT
            sim.message = "duration elapsed"

    def results(self) -> dict[str, SimulationResult]:
        """Each vehicle's run so far."""
        return {m.name: m.simulator.result() for m in self.members}

    def _worst(self) -> tuple[RunStatus, str]:
        """The fleet's status: its worst vehicle's (crashed > diverged > aborted > timeout > completed)."""
        worst = max(self.members, key=lambda m: _SEVERITY[m.simulator.status or RunStatus.COMPLETED])
        status = worst.simulator.status or RunStatus.COMPLETED
        if status == RunStatus.COMPLETED:
            return status, "every vehicle's run completed"
        return status, f"{worst.name}: {worst.simulator.message}"

    @property
    def wall_time_s(self) -> float:
        return self._wall

    # -- coupling ----------------------------------------------------------------------------------------------
    def _poses(self) -> tuple[np.ndarray, np.ndarray]:
        p = np.array([m.simulator.vehicle.state.p for m in self.members])  # type: ignore[union-attr]
        q = np.array([m.simulator.vehicle.state.q for m in self.members])  # type: ignore[union-attr]
        return p, q

    def _interact(self, now_ns: int) -> None:
        t = now_ns / NS
        for observe in self.observers:
            observe(t)
        n = len(self.members)
        if n < 2:
            return
        p, q = self._poses()
        d = np.linalg.norm(p[:, None, :] - p[None, :, :], axis=2)
        iu = self._pairs
        k = int(np.argmin(d[iu]))
        i, j = int(iu[0][k]), int(iu[1][k])
        if d[i, j] < self.min_separation_m:
            self.min_separation_m = float(d[i, j])
            self.min_separation_at = (t, self.names[i], self.names[j])
        self._contacts(t, p, q, d)
        if self.status is not None:
            return
        views = self._k % self.view_every == 0 and self.viewers_any
        if self.downwash is None and not views:
            return
        R = quat_to_matrix(q, normalize=True)  # (n, 3, 3)
        if self.downwash is not None:
            self._apply_downwash(p, R, d)
        if views:
            self._update_views(p, R, d)

    @property
    def viewers_any(self) -> bool:
        return any(m.viewers for m in self.members)

    def _contacts(self, t: float, p: np.ndarray, q: np.ndarray, d: np.ndarray) -> None:
        radii = self._box_radii
        near = np.argwhere(np.triu(d <= radii[:, None] + radii[None, :], 1))  # closer than any two points of theirs
        for i, j in near.tolist():
            other = World("vehicle")
            other.add_mesh(box_mesh_W(self._boxes[j], p[j], q[j]), self._boxes[j].triangles, label=self.names[j])
            hit = CollisionChecker(other, box_size=self._boxes[i].size).check(p[i], q[i])
            if hit is None or hit.distance >= 0.0:
                continue
            a, b = self.names[i], self.names[j]
            self.collisions.append(
                FleetCollision(
                    t, a, b, (float(hit.point_W[0]), float(hit.point_W[1]), float(hit.point_W[2])), -hit.distance
                )
            )
            where = ", ".join(f"{x:.3f}" for x in hit.point_W)
            for me, them in ((i, b), (j, a)):
                sim = self.members[me].simulator
                sim.status, sim.message = (
                    RunStatus.CRASHED,
                    f"collided with vehicle {them} at ({where}) m at t = {t:.3f} s",
                )
            self.status = RunStatus.CRASHED
            self.message = f"vehicles {a} and {b} collided at ({where}) m at t = {t:.3f} s"
            return

    def _apply_downwash(self, p: np.ndarray, R: np.ndarray, d: np.ndarray) -> None:
        cfg = self.downwash
        assert cfg is not None
        w = np.array([m.simulator.vehicle.state.rotor_speeds for m in self.members])  # type: ignore[union-attr]
        thrust = self._k_f * np.sum(w * w, axis=1)
        # which vehicle may be in which jet: s along j's axis (-z_B), r from it; i's rotors lie within
        # self._span[i] of its centre, j's jet within jet_reach(s) of its axis
        axes = -R[:, :, 2]
        rel = p[None, :, :] - p[:, None, :]  # rel[j, i] = p_i - p_j
        s_ji = np.einsum("jik,jk->ji", rel, axes)
        r_ji = np.linalg.norm(rel - s_ji[:, :, None] * axes[:, None, :], axis=2)
        span = self._span[None, :]
        reach = jet_reach(s_ji + span, self._radii[:, None]) + span
        may = (s_ji > -span) & (r_ji <= reach) & (d.T <= cfg.max_range_m) & (thrust > 0)[:, None]
        np.fill_diagonal(may, False)
        # only the vehicles some jet may reach, and those a jet reached at the last instant (back to no force)
        todo = np.flatnonzero(may.any(axis=0) | self._forces.any(axis=1))
        if not len(todo):
            return
        thrust_of = thrust.tolist()
        for i in todo.tolist():
            m = self.members[i]
            sources = [
                (thrust_of[j], p[j], R[j], self.members[j].rotor_radius_m) for j in np.flatnonzero(may[:, i]).tolist()
            ]
            force = np.zeros(3)
            if sources:
                rotors_W = p[i] + self._rotors_B[i] @ R[i].T
                force = downwash_force(cfg, sources, rotors_W, m.rotor_radius_m)
            if not np.array_equal(force, self._forces[i]):  # untouched while nothing changes: a lone run's bits
                m.simulator.vehicle.force_ext_W[:] += force - self._forces[i]  # type: ignore[union-attr]
                self._forces[i] = force

    @property
    def downwash_forces(self) -> dict[str, np.ndarray]:
        """The downwash force [N, world] each vehicle is under now."""
        return {m.name: self._forces[i].copy() for i, m in enumerate(self.members)}

    def _update_views(self, p: np.ndarray, R: np.ndarray, d: np.ndarray) -> None:
        corners_W = np.einsum("nvk,nlk->nvl", self._box_vertices_B, R) + p[:, None, :]  # (n, 8, 3)
        ranges = np.array([self.view_range_m if m.view_range_m is None else m.view_range_m for m in self.members])
        in_range = d <= ranges[:, None] + self._box_radii[None, :]
        np.fill_diagonal(in_range, False)
        for i, m in enumerate(self.members):
            if not m.viewers:
                continue
            near = np.flatnonzero(in_range[i])
            seen: World | None
            if len(near):
                tris = self._view_triangles[: 12 * len(near)]
                seen = WorldWithVehicles(m.world, corners_W[near].reshape(-1, 3), tris)
            else:
                seen = m.world
            for c in m.viewers:
                c.world = seen
