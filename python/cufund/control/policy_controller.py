"""The controller kind ``policy``: a learned policy exported by ``cufund train`` (``policy.onnx`` + ``policy.yaml``)
run by onnxruntime as a component at its trained rate.

Like the other controllers it reads the state estimate (position, velocity, attitude) and, with an estimator
attached, the IMU's gyro for the body rate (rotated by the IMU mounting and low-passed, :class:`GyroInput`), never
ground truth. From them and its targets it builds the observation of :mod:`cufund.control.policy_observation` (the
same function the environments are tested against), runs the network and turns the action in [-1, 1]^4 into
commands as the environments do (:mod:`cufund.control.policy_action`):

- ``rotor_speeds``: rotor speeds about hover, published as the :class:`ActuatorCommand` directly;
- ``thrust_rates``: collective thrust and body rates, published as a :class:`RateSetpoint` for cufund's rate loop
  (:class:`RateController`, built with it at the scenario's ``rates.rate_hz``);
- ``velocity``: a velocity setpoint turned into thrust and rates as the environments do, through the same rate
  loop.

Targets (``targets:``): ``setpoint`` (default) puts the latest ``TrajectorySetpoint`` position in every target
block, so the policy holds a point that moves along the scenario's reference (what a policy sees past the last
waypoint in training); a policy trained on a timed reference (its ``policy.yaml`` has ``lookahead_s`` > 0) gets
block k the setpoint extrapolated k * lookahead_s ahead from its velocity and acceleration, as in training
(:func:`cufund.control.policy_observation.lookahead_targets`); ``waypoints`` flies the scenario's ``trajectory.waypoints`` as the ``Waypoints`` task does
(the next ``n_targets`` in order, the current one counted reached within ``reach_radius``).

The model is refused at build time, naming the field, when its ``policy.yaml`` does not match what this controller
builds: the observation layout or its version, the observation or action size, target blocks of other than 3
numbers (a Gates policy's), or a vehicle preset other than the scenario's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cufund.core.build_context import BuildContext
from cufund.core.components import BusView, Controller
from cufund.core.config import ConfigError, nested
from cufund.core.messages import ActuatorCommand, Odometry, RateSetpoint, Topics
from cufund.core.registry import Kind, register

from . import policy_observation as po
from .arming import Gate, gate, gated, make_armable
from .gyro_input import GyroInput
from .policy_action import ActionDecoder
from .policy_manifest import PolicyManifest
from .rate_control import RateController, RateControlParams

__all__ = ["PolicyController", "PolicyControllerParams", "load_policy"]

TARGET_SOURCES = ("setpoint", "waypoints")


@dataclass(frozen=True)
class PolicyControllerParams:
    """The ``policy`` controller kind's keys."""

    model: str = ""
    """The exported policy: ``policy.onnx`` (``policy.yaml`` beside it), or the folder holding both; relative to
    the scenario file's folder."""
    targets: str = "setpoint"
    """``setpoint`` (the latest trajectory setpoint in every target block) or ``waypoints`` (the scenario's
    waypoints in order, as the Waypoints task)."""
    reach_radius: float = 0.1
    """``waypoints``: the current waypoint counts as reached within this distance [m] (the task's)."""
    vehicle: str = ""
    """The vehicle preset the scenario flies (checked against the policy's); empty: not checked."""
    rate: RateControlParams = field(default_factory=RateControlParams)
    """thrust_rates: the gains of the rate loop the policy's rates go through."""
    gyro_cutoff_hz: float = 40.0
    """Low-pass cutoff of the gyro read for the body rate when an estimator is attached [Hz]."""

    def __post_init__(self) -> None:
        if not isinstance(self.model, str) or not self.model.strip():
            raise ConfigError("controller.model must name an exported policy (policy.onnx or its folder)")
        if self.targets not in TARGET_SOURCES:
            raise ConfigError(f"controller.targets must be one of {', '.join(TARGET_SOURCES)}, got {self.targets!r}")
        for name in ("reach_radius", "gyro_cutoff_hz"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ConfigError(f"controller.{name} must be a finite number >= 0, got {v!r}")
        object.__setattr__(self, "rate", nested(RateControlParams, self.rate, "controller.rate"))


def _paths(model: str, base_dir: str | None) -> tuple[Path, Path]:
    p = Path(model).expanduser()
    if not p.is_absolute() and base_dir is not None:
        p = Path(base_dir) / p
    if p.is_dir():
        p = p / "policy.onnx"
    y = p.with_name("policy.yaml") if p.name == "policy.onnx" else p.with_suffix(".yaml")
    if not p.is_file():
        raise ConfigError(f"controller.model: no exported policy at {p} (expected policy.onnx from cufund train)")
    if not y.is_file():
        raise ConfigError(f"controller.model: {p} has no manifest beside it ({y.name})")
    return p, y


def load_policy(model: str | Path, base_dir: str | None = None, vehicle: str = "") -> tuple[Any, PolicyManifest, Path]:
    """An onnxruntime session of the exported policy, its manifest (checked: layout, version, sizes, the vehicle
    when given) and the ONNX file's path."""
    onnx_path, yaml_path = _paths(str(model), base_dir)
    manifest = PolicyManifest.read(yaml_path)
    manifest.check_layout(str(yaml_path))
    if vehicle and manifest.vehicle != vehicle:
        raise ConfigError(
            f"{yaml_path}: vehicle is {manifest.vehicle!r}, the scenario flies {vehicle!r}: a policy flies the vehicle "
            f"it was trained on (cufund train ... with env_kwargs: {{vehicle: {vehicle}}})"
        )
    try:
        import onnxruntime as ort
    except ImportError:  # pragma: no cover - depends on the install
        raise ConfigError("the policy controller needs onnxruntime: pip install 'cufund[train]'") from None
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1
    opts.inter_op_num_threads = 1
    try:
        sess = ort.InferenceSession(str(onnx_path), opts, providers=["CPUExecutionProvider"])
    except Exception as e:  # onnxruntime raises its own types for a broken file
        raise ConfigError(f"controller.model: onnxruntime cannot load {onnx_path}: {e}") from None
    inputs, outputs = sess.get_inputs(), sess.get_outputs()
    if len(inputs) != 1 or inputs[0].type != "tensor(float)":
        found = [(i.name, i.type) for i in inputs]
        raise ConfigError(f"{onnx_path}: its inputs are {found}, expected one float tensor (the observation)")
    shape = inputs[0].shape
    if len(shape) != 2 or shape[1] != manifest.obs_dim:
        raise ConfigError(f"{onnx_path}: its input is {shape}, but policy.yaml says obs_dim={manifest.obs_dim}")
    out = outputs[0].shape
    if len(out) != 2 or out[1] != manifest.act_dim:
        raise ConfigError(f"{onnx_path}: its output is {out}, but policy.yaml says act_dim={manifest.act_dim}")
    return sess, manifest, onnx_path


class PolicyController(Controller):
    """Runs an exported policy at its trained rate (see the module docstring)."""

    name = "policy_controller"
    optional_reads = (Topics.TRAJECTORY_SETPOINT,)
    armable = False
    """Gated by a commander's vehicle status (:func:`cufund.control.arming.make_armable`)."""

    def __init__(
        self,
        session: Any,
        manifest: PolicyManifest,
        decoder: ActionDecoder,
        targets: str = "setpoint",
        waypoints: tuple[tuple[float, float, float], ...] = (),
        reach_radius: float = 0.1,
        q_BI: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0),
        gyro_cutoff_hz: float = 40.0,
    ) -> None:
        if targets == "waypoints" and not waypoints:
            raise ConfigError("controller.targets: waypoints needs the scenario's trajectory.waypoints")
        if manifest.target_dim != 3:
            raise ConfigError(
                f"policy.yaml: target_dim is {manifest.target_dim} ({manifest.task}), but the policy controller builds "
                "target blocks of 3 (positions; no gate normals)"
            )
        if targets == "waypoints" and manifest.lookahead_s > 0:
            raise ConfigError(
                f"controller.targets: waypoints, but the policy was trained on a timed reference (lookahead_s "
                f"{manifest.lookahead_s:g} in its policy.yaml): its target blocks are a moving point and its "
                "extrapolations, not the next waypoints; fly it with targets: setpoint"
            )
        self.session = session
        self.manifest = manifest
        self.decoder = decoder
        self.params = decoder.params
        """The vehicle's nominal params (the arming gate's idle speed)."""
        self.rate_hz = manifest.rate_hz
        self.targets = targets
        self.waypoints = np.asarray(waypoints, dtype=np.float64).reshape(-1, 3)
        self.reach_radius = float(reach_radius)
        self.gyro = GyroInput(q_BI, gyro_cutoff_hz)
        self.use_gyro = False
        self.writes = (Topics.ACTUATOR_COMMAND,) if decoder.action_mode == "rotor_speeds" else (Topics.RATE_SETPOINT,)
        self._input = session.get_inputs()[0].name
        self.reset()

    def use_estimator(self, attached: bool) -> None:
        self.use_gyro = attached

    @property
    def inputs(self) -> tuple[str, ...]:  # type: ignore[override]
        return (self.active_state_topic, Topics.IMU) if self.use_gyro else (self.active_state_topic,)

    def reset(self) -> None:
        self.gyro.reset()
        self.a_prev = np.zeros(po.ACTION_SIZE)
        self.index = 0
        """``waypoints``: the current waypoint."""
        self.last_obs: np.ndarray | None = None
        self.last_action: np.ndarray | None = None

    def setup(self, bus: BusView) -> None:
        if self.use_gyro:
            self.gyro.setup(bus)

    def target_points(self, p_W: np.ndarray, bus: BusView) -> np.ndarray | None:
        """The K target positions (K, 3) of this step, or None before there is one."""
        k = self.manifest.n_targets
        if self.targets == "waypoints":
            wp = self.waypoints
            while self.index < len(wp) - 1 and np.linalg.norm(wp[self.index] - p_W) < self.reach_radius:
                self.index += 1
            idx = np.minimum(self.index + np.arange(k), len(wp) - 1)
            return wp[idx]
        sp = bus.latest(Topics.TRAJECTORY_SETPOINT)
        if sp is None:
            return None
        if self.manifest.lookahead_s > 0:  # a timed-reference policy: the setpoint extrapolated as in training
            return po.lookahead_targets(sp.p_W, sp.v_W, sp.a_W, k, self.manifest.lookahead_s)
        return np.repeat(np.asarray(sp.p_W, dtype=np.float64)[None, :], k, axis=0)

    def update(self, t: float, state: Odometry, bus: BusView) -> None:
        if self.decoder.action_mode == "rotor_speeds":
            if gated(self, t, bus, "policy"):  # publishes the stopped or idle rotors itself
                return
        elif self.armable and gate(bus, "policy") is not Gate.FLY:
            # the rate loop after it (gated as "policy" too) stops or idles the rotors
            self.reset()
            if self.use_gyro:
                self.gyro.update()
            return
        w_B = state.w_B
        if self.use_gyro:
            w = self.gyro.update()
            if w is None:
                return
            w_B = w
        targets = self.target_points(np.asarray(state.p_W, dtype=np.float64), bus)
        if targets is None:
            return
        obs = po.build_observation(targets, state.p_W, state.v_W, state.q_WB, w_B, self.a_prev)
        a = np.asarray(self.session.run(None, {self._input: obs[None, :]})[0], dtype=np.float64).reshape(-1)
        if a.shape != (po.ACTION_SIZE,) or not np.all(np.isfinite(a)):
            # a network that gives NaN flies nothing new: the last command holds (and the log says why)
            return
        a = np.clip(a, -1.0, 1.0)
        self.a_prev = a
        self.last_obs, self.last_action = obs, a
        if self.decoder.action_mode == "thrust_rates":
            thrust, w_sp = self.decoder.thrust_rates(a)
            bus.publish(Topics.RATE_SETPOINT, RateSetpoint(t, w_sp, thrust))
        elif self.decoder.action_mode == "velocity":
            thrust, w_sp = self.decoder.velocity(a, state.v_W, state.q_WB)
            bus.publish(Topics.RATE_SETPOINT, RateSetpoint(t, w_sp, thrust))
        else:
            bus.publish(Topics.ACTUATOR_COMMAND, ActuatorCommand(t, self.decoder.rotor_speeds(a)))


def _scenario_vehicle(config: Any) -> str:
    """The vehicle preset a scenario flies (its ``vehicle:`` name, or ``preset:`` of a mapping), or ''."""
    v = getattr(config, "vehicle", "")
    if isinstance(v, str):
        return v
    if isinstance(v, dict):
        return str(v.get("preset", ""))
    return ""


def _policy(p: PolicyControllerParams, ctx: BuildContext) -> list[Any]:
    vehicle = p.vehicle or _scenario_vehicle(ctx.config)
    session, manifest, _ = load_policy(p.model, ctx.base_dir, vehicle=vehicle)
    q_BI = tuple(ctx.imu_params().q_BI) if ctx.imu_params() is not None else (1.0, 0.0, 0.0, 0.0)
    waypoints = tuple(tuple(w) for w in ctx.config.trajectory.waypoints) if p.targets == "waypoints" else ()
    components: list[Any] = [
        PolicyController(
            session,
            manifest,
            ActionDecoder(ctx.vehicle, manifest),
            targets=p.targets,
            waypoints=waypoints,
            reach_radius=p.reach_radius,
            q_BI=q_BI,
            gyro_cutoff_hz=p.gyro_cutoff_hz,
        )
    ]
    if manifest.action_mode != "rotor_speeds":
        rate = RateController(
            ctx.vehicle, p.rate, rate_hz=ctx.config.rates.rate_hz, q_BI=q_BI, gyro_cutoff_hz=p.gyro_cutoff_hz
        )
        rate.gate_kind = "policy"
        components.append(rate)
    if ctx.commander is not None:
        make_armable(components)
    return components


register(
    Kind(
        "controller",
        "policy",
        PolicyControllerParams,
        _policy,
        None,
        "a learned policy exported by cufund train (ONNX, onnxruntime) at its trained rate; thrust_rates and "
        "velocity through the rate loop",
    )
)
