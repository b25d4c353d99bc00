"""An IMU part after the calibration a flight stack runs on it (PX4's accelerometer calibration)."""

from __future__ import annotations

import dataclasses

from .imu import ImuParams

__all__ = ["after_calibration"]


def after_calibration(part: ImuParams, accel_residual_bias: float = 0.0) -> ImuParams:
    """``part`` with its accelerometer's raw turn-on bias (the datasheet's zero-g offset, e.g. +-20 mg) replaced by
    what a calibration leaves: a bias of standard deviation ``accel_residual_bias`` per axis [m/s^2] (offset drift
    with temperature and time since the calibration; 0: a perfect calibration). The gyroscope is left as it is:
    its turn-on bias is estimated on the pad at every start, by PX4 as by cufund's estimators."""
    if not (isinstance(accel_residual_bias, (int, float)) and 0.0 <= accel_residual_bias < 10.0):
        raise ValueError(f"accel_residual_bias must be a number in [0, 10) [m/s^2], got {accel_residual_bias!r}")
    return dataclasses.replace(part, accel=dataclasses.replace(part.accel, turn_on_bias=float(accel_residual_bias)))
