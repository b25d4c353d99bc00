"""Building a scenario's component graph, validating it, running it, and measuring what its parts allow."""

from __future__ import annotations

import dataclasses
import signal
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cufund.core.build_context import BuildContext, DoneCondition, MetricHook, OutputHook, PartView
from cufund.core.config import ConfigError
from cufund.core.messages import Odometry, Topics
from cufund.core.registry import lookup
from cufund.geometry import quat_mul, yaw_quaternion
from cufund.missions.failsafe_build import failsafe_components, failsafe_done
from cufund.missions.land_detector import land_detector_components, land_detector_done
from cufund.sensors.faults import fault_summary, inject_faults
from cufund.sensors.power_monitor import PowerMonitor
from cufund.simulator import SimulationResult, Simulator
from cufund.vehicle.quadrotor import Quadrotor
from cufund.worlds.atmosphere import apply_atmosphere
from cufund.worlds.collision import CollisionChecker
from cufund.worlds.surfaces import apply_ground_effect

from .realism import Realism, resolve
from .schema import PartSpec, ScenarioConfig

__all__ = [
    "BuildContext",
    "Built",
    "ScenarioBuildContext",
    "RunInterrupted",
    "RunSummary",
    "ScenarioRun",
    "build_simulation",
    "odometry_metrics",
    "run_built",
    "run_scenario",
    "tracking_metrics",
]


class RunInterrupted(KeyboardInterrupt):
    """A run stopped by a signal (``signum``: SIGINT or SIGTERM); a KeyboardInterrupt, so code that lets Ctrl-C
    through lets it through."""

    received: int | None = None
    """The signal :meth:`raise_for` was called for (None: none yet). Kept because an exception raised inside a
    Python callback of compiled code may reach the caller as another type."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)

    @classmethod
    def raise_for(cls, signum: int) -> None:
        """What a signal handler calls: records ``signum``, then raises."""
        cls.received = int(signum)
        raise cls(signum)

    @classmethod
    def check(cls) -> None:
        """Raises if a signal came since the run started: the handler's own exception can be swallowed where it
        lands (compiled code that catches everything around a Python callback), so the run loop checks too."""
        if cls.received is not None:
            raise cls(cls.received)


class ScenarioBuildContext:
    """The :class:`~cufund.core.build_context.BuildContext` of one scenario being built: what a kind's
    ``build(params, ctx)`` may read (the scenario, the vehicle's params, the world, the sensors and their
    extrinsics, the part being built) and the declared calls through which a part adds to the run (its reference,
    its end condition, its commander, its metrics and run-folder files). Slotted: a kind that writes an attribute
    the protocol does not declare gets an AttributeError, not a silent new field."""

    __slots__ = (
        "config",
        "vehicle",
        "base_dir",
        "_realism",
        "_world",
        "world_readers",
        "_part",
        "where",
        "seed",
        "reference",
        "tracking_path",
        "commander",
        "_done",
        "_done_by",
        "_metric_hooks",
        "_output_hooks",
    )

    def __init__(self, config: ScenarioConfig) -> None:
        self.config = config
        self.vehicle = config.vehicle_params()
        self.base_dir = config.base_dir
        self._realism = resolve(config.realism, config.sensors, self.seed_for)
        self._world: Any = None
        self.world_readers: list[str] = []
        """Who read ``world`` (or ``require_world()``): the part being built (``sensors.lidar``, ``planner``, ...),
        or ``(after the build)``; ``truth_world_for_metrics()`` is not recorded. Flight software must not appear."""
        self._part: PartView | None = None
        self.where = ""
        self.seed = 0
        self.reference: Any = None
        self.tracking_path: Any = None
        self.commander: Any = None
        self._done: DoneCondition | None = None
        self._done_by = ""
        self._metric_hooks: list[MetricHook] = []
        self._output_hooks: list[OutputHook] = []

    @property
    def world(self) -> Any:
        """The scenario's world, the truth the simulated sensors see; each read is recorded in ``world_readers``."""
        who = self.where or "(after the build)"
        if who not in self.world_readers:
            self.world_readers.append(who)
        return self._world

    @world.setter
    def world(self, value: Any) -> None:
        self._world = value

    def truth_world_for_metrics(self) -> Any:
        """The world for harness-only truth consumers (metrics, collision checks, plots), not recorded as a read:
        never hand it to flight software. Refused while a part is being built (a hook calls it when it runs, after
        the build): a kind that needs the world at build time reads ``world``, and is recorded."""
        if self._part is not None:
            raise RuntimeError(
                f"{self.where}: truth_world_for_metrics() is for metric hooks and the harness, called after the build; "
                "a part that needs the world while it is built reads ctx.world (recorded as a truth read)"
            )
        return self._world

    @property
    def realism(self) -> Realism:
        """The scenario's resolved realism profile and this run's drawn errors (read-only); only the simulated
        sensors and plant apply it, flight software reads the stated extrinsics and the nominal ``vehicle``."""
        return self._realism

    @property
    def part(self) -> PartView:
        """The part being built (only while a kind's ``build`` runs)."""
        if self._part is None:
            raise RuntimeError("no part is being built: ctx.part is read inside a kind's build(params, ctx)")
        return self._part

    def seed_for(self, where: str) -> int:
        """The seed of the random stream of the part at ``where`` (e.g. ``sensors.lidar``): derived from the
        scenario seed and the name, so adding a part does not change another's stream."""
        return int(np.random.SeedSequence([self.config.seed, zlib.crc32(where.encode())]).generate_state(1)[0])

    def require_world(self) -> Any:
        if self.world is None:
            raise ConfigError(f"{self.where} needs a world to sense (set world: ..., e.g. world: empty)")
        return self.world

    def sensor_of_type(self, sensor_type: str, name: str = "", where: str = "") -> tuple[str, PartSpec]:
        """The sensor called ``name``, or the only sensor of ``sensor_type`` (or the one named after the type)."""
        sensors = self.config.sensors
        where = where or self.where
        if name:
            spec = sensors.get(name)
            if spec is None or spec.sensor_type != sensor_type:
                raise ConfigError(f"{where}: no {sensor_type} sensor named {name!r} in sensors")
            return name, spec
        found = [(n, s) for n, s in sensors.items() if s.sensor_type == sensor_type]
        if len(found) > 1:
            named = [(n, s) for n, s in found if n == sensor_type]
            if named:
                return named[0]
            raise ConfigError(f"{where}: several {sensor_type} sensors ({', '.join(n for n, _ in found)}); name one")
        if not found:
            raise ConfigError(f"{where} needs a {sensor_type} sensor; add one under sensors")
        return found[0]

    def imu_params(self) -> Any:
        """The IMU's params with its mounting applied (None without an IMU)."""
        try:
            _, spec = self.sensor_of_type("imu")
        except ConfigError:
            return None
        p = spec.params
        if spec.extrinsic is not None:
            p = dataclasses.replace(p, p_BI=spec.extrinsic.t, q_BI=spec.extrinsic.q)
        return p

    def set_reference(self, reference: Any, tracking_path: Any = None) -> None:
        """A planner declares the reference it flies (and the part of it tracking error is measured over)."""
        self.reference, self.tracking_path = reference, tracking_path

    def set_done_condition(self, done: DoneCondition) -> None:
        """Declares when the run ends; a second part declaring one is a ConfigError naming both."""
        if not callable(done):
            raise TypeError(f"{self.where}: set_done_condition takes done(t, truth) -> bool, got {done!r}")
        if self._done is not None:
            raise ConfigError(
                f"{self.where}: the run's end condition is declared already by {self._done_by}; one "
                "part per scenario may end the run"
            )
        self._done, self._done_by = done, self.where

    def set_commander(self, commander: Any) -> None:
        """Declares the vehicle commander: the controllers built from here on are gated by its status."""
        if commander is None:
            raise TypeError(f"{self.where}: set_commander takes the commander component, got None")
        if self.commander is not None and self.commander is not commander:
            raise ConfigError(f"{self.where}: a commander is declared already; a scenario has one")
        self.commander = commander

    def add_metric_hook(self, hook: MetricHook) -> None:
        """``hook(result) -> dict`` merged into the run's metrics (e.g. a replanner's planning metrics)."""
        if not callable(hook):
            raise TypeError(f"{self.where}: add_metric_hook takes hook(result) -> dict, got {hook!r}")
        self._metric_hooks.append(hook)

    def add_output_hook(self, hook: OutputHook) -> None:
        """``hook(run, out, **kw)`` writes a part's own files into the run folder ``out`` (e.g. a mission's plots)."""
        if not callable(hook):
            raise TypeError(f"{self.where}: add_output_hook takes hook(run, out, **kw), got {hook!r}")
        self._output_hooks.append(hook)

    @property
    def done_condition(self) -> DoneCondition | None:
        """The end condition a part declared, or None."""
        return self._done

    @property
    def metric_hooks(self) -> tuple[MetricHook, ...]:
        return tuple(self._metric_hooks)

    @property
    def output_hooks(self) -> tuple[OutputHook, ...]:
        return tuple(self._output_hooks)

    def build(self, group: str, spec: PartView, where: str) -> Any:
        """Builds the part ``spec`` of ``group`` at ``where``: the world, or its list of components (with the
        part's latency and phase set). ``part``, ``where`` and ``seed`` are the caller's again afterwards (a part
        may build another, e.g. a second controller)."""
        kind = lookup(group, spec.kind, where)
        saved = self._part, self.where, self.seed
        self._part, self.where, self.seed = spec, where, self.seed_for(where)
        try:
            out = kind.build(spec.params, self)
        except ConfigError:
            raise
        except (TypeError, ValueError) as e:
            raise ConfigError(f"{where} ({spec.kind}): {e}") from None
        finally:
            self._part, self.where, self.seed = saved
        if group == "world":
            return out
        components = list(out)
        for c in components:
            if spec.latency_s:
                c.latency_s = spec.latency_s
            if spec.phase_s:
                c.phase_s = spec.phase_s
        return components


_CONFORMS: type[BuildContext] = ScenarioBuildContext  # mypy checks the class against the protocol here


@dataclass
class Built:
    """A scenario ready to run."""

    config: ScenarioConfig
    simulator: Simulator
    context: ScenarioBuildContext
    landing_after: float | None
    """The reference ends (landed) at this time [s]; None without a reference."""


def build_simulation(config: ScenarioConfig, extra_components: tuple = (), logger: Any = None) -> Built:
    """The vehicle, world, components and simulator of ``config``, validated: unknown kinds, bad params, an
    unsatisfied input ("planner needs /map/esdf; nothing publishes it"), ground truth read by flight software,
    or a zero-latency cycle raise :class:`ConfigError` naming the part — before anything runs."""
    if config.vehicles:
        raise ConfigError(
            f"scenario {config.name!r} lists vehicles: a fleet, built by cufund.scenarios.fleet.build_fleet"
        )
    ctx = ScenarioBuildContext(config)
    if config.world is not None:
        ctx.world = ctx.build("world", config.world, "world")
    world = ctx.truth_world_for_metrics()  # the harness's (the vehicle's start, collision checks)
    quad = Quadrotor(ctx.realism.simulated_vehicle(ctx.vehicle))  # the plant; controllers read ctx.vehicle
    start = config.start_p_W or (config.trajectory.waypoints[0][0], config.trajectory.waypoints[0][1], 0.0)
    quad.state.p[:] = start  # standing, rotors stopped
    quad.state.q[:] = quad.params.ground_attitude  # on the pad as it lies (realism.vehicle.pad_tilt_max_deg)
    if config.start_yaw:  # facing start_yaw, the pad's tilt turned with it
        quad.state.q[:] = quat_mul(yaw_quaternion(config.start_yaw), quad.params.ground_attitude)
    apply_atmosphere(quad, config.atmosphere, ctx.seed_for("atmosphere"), config.base_dir)  # null: still air
    apply_ground_effect(quad, config.ground_effect, world)  # null: off
    collision = None
    if world is not None:
        collision = CollisionChecker(world, box_size=config.collision_box, ignore_labels=("floor", "ground"))
    record = [Topics.TRAJECTORY_SETPOINT, Topics.ATTITUDE_SETPOINT, Topics.ACTUATOR_COMMAND]
    components: list[Any] = []
    for name, spec in config.sensors.items():
        components += ctx.build("sensor", spec, f"sensors.{name}")
        record.append(spec.topic)
    components = inject_faults(config.faults, config.sensors, components, ctx.seed_for, quad, config.rates.physics_hz)
    power = config.power_system()
    if power is not None:  # vehicle.battery: the pack on the plant (its voltage limits the rotors) and its reading
        monitor = PowerMonitor(power, quad.params, quad, ctx.seed_for("vehicle.battery"))
        components.append(monitor)
        record.append(Topics.BATTERY)
        ctx.add_metric_hook(monitor.metrics)  # battery_used_mah, battery_min_voltage_v
    for group in ("estimator", "mapper", "perception", "planner", "controller", "mission"):
        spec = getattr(config, group)
        if spec is not None:
            components += ctx.build(group, spec, group)
    components += failsafe_components(config.failsafe or None, ctx, components)  # takes over the reference
    components += land_detector_components(ctx, components)  # a follower's landing: touchdown, disarm
    if config.ros2 is not None:  # the ROS 2 bridge (cufund.apps.ros2, registered as the bridge kind ros2)
        components += ctx.build("bridge", config.ros2, "ros2")
    if config.estimator is not None:
        record += [Topics.ESTIMATE, Topics.ESTIMATOR_DIAGNOSTICS]
    sim = Simulator(
        quad,
        physics_rate_hz=config.rates.physics_hz,
        record_topics=_recordable(record, components),
        collision=collision,
        logger=logger,
    )
    for c in (*components, *extra_components):
        sim.add(c)
    problems = sim.wiring()
    if problems:
        raise ConfigError("; ".join(problems))
    landing_after = ctx.reference.t_end if ctx.reference is not None else None
    return Built(config, sim, ctx, landing_after)


def _recordable(record: list[Any], components: list[Any]) -> list[Any]:
    """The topics worth keeping in memory for the run's plots and metrics (not point clouds or images)."""
    published = {str(t) for c in components for t in c.outputs}
    keep: list[Any] = []
    for t in record:
        if (
            str(t) in published
            and str(t) not in {str(k) for k in keep}
            and not str(t).startswith(("/sensors/lidar", "/sensors/depth", "/sensors/rgb"))
            and getattr(getattr(t, "type", None), "__name__", "") not in ("PointCloud", "CameraImage")
        ):
            keep.append(t)
    return keep


@dataclass
class RunSummary:
    """What a run leaves behind, small and picklable: metrics, status, message and the run folder's files."""

    metrics: dict[str, Any]
    status: str
    message: str
    paths: dict[str, str] = field(default_factory=dict)


@dataclass
class ScenarioRun:
    """A finished scenario: the simulator's result, the flown reference, and the metrics of its parts."""

    config: ScenarioConfig
    result: SimulationResult
    reference: Any
    path: Any
    """The part of the reference tracking error is measured over (the min-snap path), or None."""
    metrics: dict[str, Any]
    output_hooks: list[Any] = field(default_factory=list)
    """The parts' ``hook(run, out)`` writing their own files into the run folder."""

    def summary(self, paths: dict[str, str] | None = None) -> RunSummary:
        return RunSummary(dict(self.metrics), self.result.status.value, self.result.message, dict(paths or {}))


def run_scenario(
    config: ScenarioConfig, progress: bool = False, extra_components: tuple = (), logger: Any = None
) -> ScenarioRun:
    """Builds ``config`` (:func:`build_simulation`), runs it until the vehicle has landed after its reference (or
    the duration elapses), and measures it: tracking error when there is a reference, odometry error when there is
    an estimator (both against ground truth, which only these metrics read)."""
    return run_built(build_simulation(config, extra_components, logger), progress)


def run_built(built: Built, progress: bool = False) -> ScenarioRun:
    """Runs a scenario made by :func:`build_simulation` (see :func:`run_scenario`)."""
    result = built.simulator.run(built.config.duration, done=done_condition(built), progress=progress)
    return measure_run(built, result)


def done_condition(built: Built) -> Any:
    """``done(t, truth)`` of a built scenario: landed after its reference, or a part's end condition (through the
    failsafe supervisor's); also raises :class:`RunInterrupted` on a signal received."""
    t_landed = built.landing_after

    def landed(t: float, truth: Odometry) -> bool:
        return (
            t_landed is not None and t >= t_landed and truth.p_W[2] < 0.02 and float(np.linalg.norm(truth.v_W)) < 0.05
        )

    ctx = built.context
    finished = failsafe_done(built.simulator.components, landed if t_landed is not None else ctx.done_condition)
    finished = land_detector_done(built.simulator.components, finished)

    def done(t: float, truth: Odometry) -> bool:
        RunInterrupted.check()  # a SIGINT / SIGTERM whose exception was swallowed where it landed
        return finished is not None and finished(t, truth)

    return done


_LIO_METRICS = (
    "lio_ms_per_scan_median",
    "lio_ms_per_scan_p99",
    "lio_cpu_ms_per_scan_median",
    "lio_scans",
    "lio_unhealthy_reports",
)
_VIO_METRICS = (
    "vio_ms_per_frame_median",
    "vio_ms_per_frame_p99",
    "vio_cpu_ms_per_frame_median",
    "vio_frames",
    "vio_unhealthy_reports",
)
"""The keys of an odometry's timing figures: a LiDAR one's per scan, a visual-inertial one's per stereo frame."""


def measure_run(built: Built, result: SimulationResult) -> ScenarioRun:
    """The metrics of a built scenario's finished run (:func:`run_built`)."""
    config, ctx = built.config, built.context
    metrics = run_metrics(result)
    metrics["failsafe_events"] = []  # always present; the supervisor's hook fills it
    metrics["realism"] = ctx.realism.summary()  # under what the figures were measured
    if config.faults:
        metrics["faults"] = fault_summary(config.faults)
    if ctx.tracking_path is not None:
        metrics.update(tracking_metrics(result, ctx.tracking_path))
    if config.estimator is not None:
        metrics.update(odometry_metrics(result))
        diag = result.topics.get(str(Topics.ESTIMATOR_DIAGNOSTICS))
        if diag:  # a LiDAR odometry's per scan, a visual-inertial one's (VioDiagnostics: tracked) per stereo frame
            median, p99, cpu, count, unhealthy = _VIO_METRICS if "tracked" in diag else _LIO_METRICS
            used = np.asarray([s == "" for s in diag["skipped"]], dtype=bool)  # frames with a LiDAR/visual constraint
            ms = np.asarray(diag["time_ms"], dtype=float)[used]
            if len(ms):
                metrics.update(
                    {
                        median: float(np.median(ms)),
                        p99: float(np.percentile(ms, 99)),
                        cpu: float(np.median(np.asarray(diag["cpu_ms"], dtype=float)[used])),
                    }
                )
            metrics[count] = int(len(ms))
            metrics[unhealthy] = int(np.count_nonzero(~np.asarray(diag["healthy"], dtype=bool)))
    for hook in ctx.metric_hooks:  # last: a part may refine a generic figure (e.g. over its flight window only)
        metrics.update(hook(result))
    return ScenarioRun(config, result, ctx.reference, ctx.tracking_path, metrics, list(ctx.output_hooks))


def run_metrics(result: SimulationResult) -> dict[str, Any]:
    out: dict[str, Any] = {
        "status": result.status.value,
        "message": result.message,
        "sim_time_s": result.sim_time_s,
        "wall_time_s": result.wall_time_s,
        "real_time_factor": result.real_time_factor,
        "component_seconds": {k: round(v, 6) for k, v in result.component_seconds.items()},
    }
    if result.dropped:
        out["dropped_messages"] = dict(result.dropped)
    return out


def tracking_metrics(result: SimulationResult, path: Any) -> dict[str, Any]:
    """|true position - reference position| at every recorded state within the path's time span."""
    t = result.states["t"]
    m = (t >= path.t_knots[0]) & (t <= path.t_end)
    err = np.linalg.norm(result.states["p_W"][m] - path.sample(t[m]).p_W, axis=1) if np.any(m) else None
    return {  # None: the run ended before the path began
        "tracking_rmse_m": None if err is None else float(np.sqrt(np.mean(err**2))),
        "tracking_max_m": None if err is None else float(np.max(err)),
        "tracking_min_m": None if err is None else float(np.min(err)),
        "tracking_window_s": [float(path.t_knots[0]), float(path.t_end)],
        "tracking_samples": int(np.count_nonzero(m)),
    }


def odometry_metrics(result: SimulationResult) -> dict[str, Any]:
    """|p_true - p_est| and the attitude error angle at each estimator output from take-off to touchdown (the pad,
    where the estimate starts, would flatter every figure), the true state interpolated at the estimate's stamp:
    unaligned (the estimator's world frame is the pad's) and as evo's aligned APE (SE(3) Umeyama, no scale). A run
    that never lifts off reports over all its outputs."""
    est = result.topics.get(str(Topics.ESTIMATE), {})
    if not est:
        return {"odometry_samples": 0}
    t_est = np.asarray(est["t"], dtype=float)
    ts, p, q = result.states["t"], result.states["p_W"], result.states["q_WB"]
    ok = (t_est >= ts[0]) & (t_est <= ts[-1])
    t_est = t_est[ok]
    p_est = np.asarray(est["p_W"], dtype=float)[ok]
    q_est = np.asarray(est["q_WB"], dtype=float)[ok]
    p_true = np.stack([np.interp(t_est, ts, p[:, i]) for i in range(3)], axis=1)
    from cufund.estimation.evaluation import aligned_ate, flight_window  # scipy only when there is odometry

    flying = flight_window(p_true[:, 2])
    if flying.stop - flying.start >= 3:
        t_est, p_est, q_est, p_true = t_est[flying], p_est[flying], q_est[flying], p_true[flying]
    i = np.clip(np.searchsorted(ts, t_est), 0, len(ts) - 1)  # the state record at (or right after) the stamp
    dot = np.abs(np.sum(q[i] * q_est, axis=1)) / np.linalg.norm(q_est, axis=1)
    ang = np.degrees(2 * np.arccos(np.clip(dot, 0.0, 1.0)))
    err = np.linalg.norm(p_true - p_est, axis=1)
    return {
        "odometry_min_m": float(np.min(err)),
        "odometry_rmse_m": float(np.sqrt(np.mean(err**2))),
        "odometry_max_m": float(np.max(err)),
        "odometry_rot_rmse_deg": float(np.sqrt(np.mean(ang**2))),
        "odometry_samples": int(len(err)),
        "odometry_window_s": [float(t_est[0]), float(t_est[-1])],
        # the error a real vehicle's figure would show, whose world frame is its estimator's own
        "odometry_ate_aligned_m": aligned_ate(p_est, p_true) if len(err) >= 3 else None,
    }


def out_dir_problem(out: str | Path) -> str | None:
    """Why a run folder cannot be written at ``out`` (None when it can), checked before a run starts."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        return f"--out {out}: exists and is not a folder"
    parent = out
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        return f"--out {out}: {parent} is not a folder"
    import os

    if not os.access(parent, os.W_OK | os.X_OK):
        return f"--out {out}: {parent} is not writable"
    return None
