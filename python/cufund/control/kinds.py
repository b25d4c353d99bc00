"""The built-in controller kinds of scenarios: ``pid`` (PX4-style cascade) and ``geometric`` (SE(3)).

Both take the same params (:class:`ControllerParams`: every gain set, so ``--set controller.kind=geometric``
switches a scenario without touching its gains); their rates are the scenario's ``rates``. With an estimator
attached, the rate loop reads the IMU named ``imu`` (or the only IMU) through its mounting.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from cufund.core.build_context import BuildContext
from cufund.core.config import ConfigError, nested
from cufund.core.registry import Kind, register

from .arming import make_armable
from .attitude_control import AttitudeController, AttitudeControlParams
from .geometric_controller import GeometricController, GeometricControlParams
from .position_control import PositionController, PositionControlParams
from .rate_control import RateController, RateControlParams

__all__ = ["ControllerParams"]


@dataclass(frozen=True)
class ControllerParams:
    """Gains of both built-in controllers (only the chosen kind's are used)."""

    position: PositionControlParams = field(default_factory=PositionControlParams)
    attitude: AttitudeControlParams = field(default_factory=AttitudeControlParams)
    rate: RateControlParams = field(default_factory=RateControlParams)
    geometric: GeometricControlParams = field(default_factory=GeometricControlParams)
    gyro_cutoff_hz: float = 40.0
    """Low-pass cutoff of the gyro the rate loop reads when an estimator is attached [Hz] (IMU_GYRO_CUTOFF)."""

    def __post_init__(self) -> None:
        for name, cls in (
            ("position", PositionControlParams),
            ("attitude", AttitudeControlParams),
            ("rate", RateControlParams),
            ("geometric", GeometricControlParams),
        ):
            try:
                object.__setattr__(self, name, nested(cls, getattr(self, name), f"controller.{name}"))
            except ValueError as e:
                raise ConfigError(str(e) if "controller." in str(e) else f"controller.{name}: {e}") from None
        v = self.gyro_cutoff_hz
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise ConfigError(f"controller.gyro_cutoff_hz must be a finite number >= 0 [Hz], got {v!r}")


def _q_BI(ctx: BuildContext) -> tuple[float, float, float, float]:
    imu = ctx.imu_params()
    return tuple(imu.q_BI) if imu is not None else (1.0, 0.0, 0.0, 0.0)


def _armable(components: list[Any], ctx: BuildContext) -> list[Any]:
    """With a commander as planner (built before the controllers), its vehicle status gates the controllers."""
    if ctx.commander is not None:
        make_armable(components)
    return components


def _pid(p: ControllerParams, ctx: BuildContext) -> list[Any]:
    r, v = ctx.config.rates, ctx.vehicle
    return _armable(
        [
            PositionController(v, p.position, rate_hz=r.position_hz),
            AttitudeController(p.attitude, rate_hz=r.attitude_hz),
            RateController(v, p.rate, rate_hz=r.rate_hz, q_BI=_q_BI(ctx), gyro_cutoff_hz=p.gyro_cutoff_hz),
        ],
        ctx,
    )


def _geometric(p: ControllerParams, ctx: BuildContext) -> list[Any]:
    return _armable(
        [
            GeometricController(
                ctx.vehicle,
                p.geometric,
                rate_hz=ctx.config.rates.geometric_hz,
                q_BI=_q_BI(ctx),
                gyro_cutoff_hz=p.gyro_cutoff_hz,
            )
        ],
        ctx,
    )


register(
    Kind(
        "controller",
        "pid",
        ControllerParams,
        _pid,
        None,
        "PX4-style cascade: position/velocity PID -> attitude P -> rate PID -> allocation",
    )
)
register(
    Kind(
        "controller",
        "geometric",
        ControllerParams,
        _geometric,
        None,
        "Lee-Leok-McClamroch SE(3) tracking controller with the same allocation",
    )
)

# the learned-policy kind (ONNX through onnxruntime) registers itself
from . import policy_controller as _policy_controller  # noqa: E402, F401
