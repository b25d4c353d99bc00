"""What an exported policy is: ``policy.yaml`` beside ``policy.onnx`` (written by ``cufund train``, read by the
``policy`` controller, which refuses a model whose observation layout, its version, its sizes or its action mode
do not match what it builds, naming the field)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from cufund.core.config import ConfigError

from . import policy_observation as po

__all__ = ["ACTION_MODES", "FORMAT", "OBS_LAYOUT", "OBS_LAYOUT_VERSION", "PolicyManifest"]

ACTION_MODES = ("rotor_speeds", "thrust_rates", "velocity")
FORMAT = "cufund-policy/1"
"""The manifest's own format: a policy.yaml of another one is refused."""
OBS_LAYOUT = "cufund.policy_observation"
"""The name of the observation layout (:mod:`cufund.control.policy_observation`)."""
OBS_LAYOUT_VERSION = po.LAYOUT_VERSION
"""Its version: a policy trained on another version sees other numbers and is refused."""


@dataclass(frozen=True)
class PolicyManifest:
    """The facts of one exported policy."""

    task: str
    """The Gymnasium id it was trained on (``cufund/Waypoints-v0``)."""
    action_mode: str
    """``rotor_speeds``, ``thrust_rates`` or ``velocity`` (cufund.envs' action modes)."""
    rate_hz: float
    """The env's step rate: the rate the policy runs at [Hz]."""
    n_targets: int
    """Target blocks in the observation."""
    target_dim: int
    """Numbers per target block (3, or 6 with gate normals)."""
    obs_dim: int
    act_dim: int
    vehicle: str
    """The vehicle preset it was trained on."""
    seed: int
    """The training run's seed."""
    obs_layout: str = OBS_LAYOUT
    obs_layout_version: int = OBS_LAYOUT_VERSION
    max_rate: float = 10.0
    """thrust_rates: the body-rate setpoint at |a| = 1 [rad/s] (the task's)."""
    max_speed: float = 2.0
    """velocity: the speed setpoint at |a| = 1 per axis [m/s] (the task's)."""
    velocity_gain: float = 4.0
    """velocity: the velocity loop's gain [1/s] (cufund.envs')."""
    attitude_gain: float = 10.0
    """velocity: the tilt loop's gain [1/s] (cufund.envs')."""
    lookahead_s: float = 0.0
    """A timed-reference waypoints policy: target block k is the reference extrapolated k * lookahead_s [s] ahead
    (the task's; 0: every block the same point)."""
    algo: str = "ppo"
    library: str = "skrl"
    env_steps: int = 0
    """Environment steps it was trained for."""
    format: str = FORMAT

    def __post_init__(self) -> None:
        if self.action_mode not in ACTION_MODES:
            raise ConfigError(
                f"policy.yaml: action_mode must be one of {', '.join(ACTION_MODES)}, got {self.action_mode!r}"
            )
        for name in ("rate_hz", "max_rate", "max_speed", "velocity_gain", "attitude_gain"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ConfigError(f"policy.yaml: {name} must be a finite number > 0, got {v!r}")
            object.__setattr__(self, name, float(v))
        v = self.lookahead_s
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise ConfigError(f"policy.yaml: lookahead_s must be a finite number >= 0, got {v!r}")
        object.__setattr__(self, "lookahead_s", float(v))
        for name in ("n_targets", "target_dim", "obs_dim", "act_dim", "seed", "env_steps", "obs_layout_version"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise ConfigError(f"policy.yaml: {name} must be a whole number >= 0, got {v!r}")

    def check_layout(self, where: str = "policy.yaml") -> None:
        """Raises :class:`ConfigError` naming the first field that does not match the observation this version of
        cufund builds (:mod:`cufund.control.policy_observation`)."""
        if self.format != FORMAT:
            raise ConfigError(f"{where}: format is {self.format!r}, this cufund reads {FORMAT!r}")
        if self.obs_layout != OBS_LAYOUT:
            raise ConfigError(f"{where}: obs_layout is {self.obs_layout!r}, expected {OBS_LAYOUT!r}")
        if self.obs_layout_version != OBS_LAYOUT_VERSION:
            raise ConfigError(
                f"{where}: obs_layout_version is {self.obs_layout_version}, this cufund builds version "
                f"{OBS_LAYOUT_VERSION}: retrain the policy (cufund train)"
            )
        try:
            expected = po.observation_size(self.n_targets, self.target_dim)
        except ValueError as e:
            raise ConfigError(f"{where}: n_targets/target_dim: {e}") from None
        if self.obs_dim != expected:
            raise ConfigError(
                f"{where}: obs_dim is {self.obs_dim}, but {self.n_targets} target block(s) of {self.target_dim} "
                f"make observations of {expected}"
            )
        if self.act_dim != po.ACTION_SIZE:
            raise ConfigError(f"{where}: act_dim is {self.act_dim}, expected {po.ACTION_SIZE}")

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    def write(self, path: str | Path) -> Path:
        path = Path(path)
        path.write_text(
            "# an exported cufund policy (cufund.control.policy_manifest); policy.onnx beside it\n"
            + yaml.safe_dump(self.to_dict(), sort_keys=False),
            encoding="utf-8",
        )
        return path

    @classmethod
    def read(cls, path: str | Path) -> PolicyManifest:
        """Reads ``policy.yaml``; a missing or unknown key is named."""
        path = Path(path)
        try:
            data = yaml.safe_load(path.read_text(encoding="utf-8"))
        except OSError as e:
            raise ConfigError(f"policy manifest {path}: cannot read it ({e.strerror})") from None
        except yaml.YAMLError as e:
            raise ConfigError(f"policy manifest {path}: not YAML ({e})") from None
        if not isinstance(data, dict):
            raise ConfigError(f"policy manifest {path}: expected a mapping of PolicyManifest keys")
        known = {f.name: f for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - set(known))
        if unknown:
            raise ConfigError(f"policy manifest {path}: unknown key(s) {unknown}")
        required = [n for n, f in known.items() if f.default is dataclasses.MISSING and n not in data]
        if required:
            raise ConfigError(f"policy manifest {path}: missing key(s) {required}")
        return cls(**data)
