"""Faults in flight, as scenario options (``faults:`` in a scenario): of the sensors and of the vehicle.

Each fault acts from a start time ``t_start`` [s] of simulated time (on a sensor's messages by their measurement
stamp, except the LiDAR's by their publication time), and changes nothing before it:

- ``lidar_dropout``: the LiDAR publishes nothing for ``duration`` s.
- ``lidar_degraded``: each frame keeps a random ``fraction`` of its points, each kept range gets Gaussian noise of
  ``noise_m`` [m] (for ``duration`` s, or for good when null).
- ``imu_bias_step``: the accelerometer reads ``accel`` [m/s^2] more and the gyroscope ``gyro`` [rad/s] more, in
  the IMU's own frame.
- ``gps_dropout``: fixes measured during ``duration`` s are no-fix reports (fix_type 0, NaN position).
- ``gps_jump``: the fixes are off by ``offset_m`` (east, north, up) [m].
- ``gps_drift``: the fixes drift off at ``rate_mps`` [m/s] (position off by rate (t - t_start), velocity by rate):
  slow spoofing.
- ``mag_disturbance``: the magnetometer reads ``field_T`` [T] more (or a field of ``magnitude_T`` in a seeded random
  direction).
- ``baro_step``: the barometer's altitude reads ``offset_m`` more (or its pressure ``offset_pa`` more).
- ``motor_failure``: rotor ``motor`` (0-3) stops: no thrust or drag torque, its speed decays with the motor lag.
- ``motor_efficiency``: rotor ``motor`` makes ``efficiency`` (0, 1] of its thrust and drag torque, reached over
  ``ramp_s``.
- ``prop_imbalance``: rotor ``motor``'s propeller is out of balance by ``imbalance_kg_m`` (m r): a centrifugal force
  m r omega^2 turning with the rotor, which reaches the IMU through the body's motion.

The GPS, magnetometer and barometer faults last for ``duration`` s, or for good when it is null (``gps_dropout``
always has one). Written as a map ``{lidar_dropout: {t_start: 12}, motor_failure: {t_start: 20, motor: 2}}`` (one
fault of a kind; overridable as ``--set faults.motor_failure.t_start=12``) or a list ``[{kind: lidar_dropout,
t_start: 12}, ...]`` (several of a kind). A sensor fault takes ``sensor``: the sensor's name under ``sensors``
(default: the only sensor of its type). The faults' random streams derive from the scenario seed (a run repeats
bit for bit); each is listed in ``metrics["faults"]``. Sensor faults wrap the sensor's component
(:class:`FaultySensor`): the sensor model itself is untouched, so the same seed gives the same clean measurements
with and without faults. The plant's faults act on the simulated vehicle through its held inputs
(:mod:`cufund.sensors.faults.plant`), never on what flight software is told.
"""

from __future__ import annotations

from .barometer import BaroStep
from .base import FaultRun, SensorFault
from .config import FAULT_KINDS, Fault, fault_summary, faults_to_data, parse_faults
from .gps import GpsDrift, GpsDropout, GpsJump
from .imu import ImuBiasStep
from .inject import FaultySensor, inject_faults
from .lidar import LidarDegraded, LidarDropout, degrade
from .magnetometer import MagDisturbance
from .plant import MotorEfficiency, MotorFailure, PlantFault, PlantFaults, PropImbalance, plant_faults

__all__ = [
    "FAULT_KINDS",
    "BaroStep",
    "Fault",
    "FaultRun",
    "FaultySensor",
    "GpsDrift",
    "GpsDropout",
    "GpsJump",
    "ImuBiasStep",
    "LidarDegraded",
    "LidarDropout",
    "MagDisturbance",
    "MotorEfficiency",
    "MotorFailure",
    "PlantFault",
    "PlantFaults",
    "PropImbalance",
    "SensorFault",
    "degrade",
    "fault_summary",
    "faults_to_data",
    "inject_faults",
    "parse_faults",
    "plant_faults",
]
