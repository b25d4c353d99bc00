"""The scenario's ``realism`` profile: how far the simulated vehicle and its sensors are from what flight software is
told (issue 31, "honest fidelity"). Values and their sources: ``docs/realism.md``.

``realism: ideal`` (the default): every term off, perfect calibration (the simulated accelerometer has no turn-on
bias, as after a perfect PX4-style calibration; every other part exactly as stated), the exact plant, a level pad.
``realism: realistic`` switches the terms on with values from datasheets and the literature. A mapping starts from a
profile and overrides fields: ``{profile: realistic, imu: {scale_factor_ppm: 3000}}`` (from the command line:
``--set realism=realistic --set realism.imu.scale_factor_ppm=3000``).

The profile holds the *spread* of each error (a standard deviation or a bound). The errors themselves are drawn once
per run by :func:`resolve` from the scenario seed (``seed_for("realism.<section>...")``: the same seed draws the same
errors, bit for bit) into a :class:`Realism`, which the build context exposes as ``ctx.realism``. Only the simulated
parts get the drawn truth (:meth:`Realism.simulated_imu`, :meth:`Realism.simulated_lidar`,
:meth:`Realism.simulated_extrinsic`, :meth:`Realism.simulated_vehicle`); flight software keeps reading the stated
extrinsics (``ctx.sensor_of_type(...).extrinsic``, ``ctx.imu_params()``) and the nominal vehicle (``ctx.vehicle``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cufund.core.config import ConfigError, from_dict, nested
from cufund.geometry import quat_from_rotvec

__all__ = [
    "PROFILES",
    "CalibrationRealism",
    "ImuRealism",
    "LidarRealism",
    "Realism",
    "RealismConfig",
    "VehicleRealism",
    "VibrationRealism",
    "resolve",
]

G0 = 9.80665
DEG = math.pi / 180.0


def _real(
    obj: Any, where: str, name: str, *, lower: float = 0.0, upper: float = math.inf, inf_ok: bool = False
) -> None:
    v = getattr(obj, name)
    ok = not isinstance(v, bool) and isinstance(v, (int, float)) and not math.isnan(v)
    ok = ok and (math.isfinite(v) or (inf_ok and v == math.inf)) and lower <= v <= upper
    if not ok:
        bound = f"in [{lower:g}, {upper:g}]" if math.isfinite(upper) else f">= {lower:g}"
        raise ConfigError(f"{where}.{name} must be a number {bound}{' (or .inf)' if inf_ok else ''}, got {v!r}")
    object.__setattr__(obj, name, float(v))


def _reals(obj: Any, where: str, name: str, dim: int | None, upper: float = math.inf) -> None:
    v = getattr(obj, name)
    try:
        a = np.asarray(v, dtype=float)
    except (TypeError, ValueError, OverflowError):
        a = np.full(0, np.nan)
    what = f"{dim} numbers" if dim is not None else "a list of numbers"
    if (
        isinstance(v, (str, bool))
        or a.ndim != 1
        or (dim is not None and a.shape != (dim,))
        or (dim is None and a.size == 0)
        or not np.all(np.isfinite(a))
        or np.any(a < 0)
        or np.any(a > upper)
    ):
        raise ConfigError(f"{where}.{name} must be {what} in [0, {upper:g}], got {v!r}")
    object.__setattr__(obj, name, tuple(float(x) for x in a))


@dataclass(frozen=True)
class VibrationRealism:
    """Rotor vibration reaching the IMU (the rotor-rate line and its harmonics), filtered by the part's anti-alias
    filter and sampled at its output rate (so it aliases). Passed to the simulated IMU's ``vibration``."""

    accel_mps2: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Amplitude of the rotor-rate line at hover rotor speed, per IMU axis [m/s^2]; it scales with
    (rotor speed / hover rotor speed)^2 and vanishes with the rotors stopped."""
    gyro_dps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """The same for the gyroscope [deg/s]."""
    harmonics: tuple[float, ...] = (1.0,)
    """Amplitude ratios of the 1x, 2x, 3x, ... rotor-rate lines [-]."""
    speed_spread: float = 0.0
    """Relative spread of the four rotors' speeds (seeded by the IMU's stream) [-]."""
    anti_alias_hz: float = 80.0
    """Corner (-3 dB) of the IMU's anti-alias filter (Butterworth), ahead of the output sampling [Hz]."""
    anti_alias_order: int = 2
    """Order of that filter."""

    def __post_init__(self) -> None:
        w = "realism.imu.vibration"
        _reals(self, w, "accel_mps2", 3, upper=1000.0)
        _reals(self, w, "gyro_dps", 3, upper=1000.0)
        _reals(self, w, "harmonics", None, upper=100.0)
        _real(self, w, "speed_spread", upper=0.5)
        _real(self, w, "anti_alias_hz", lower=1.0, upper=1e5)
        o = self.anti_alias_order
        if isinstance(o, bool) or not isinstance(o, int) or not 1 <= o <= 8:
            raise ConfigError(f"{w}.anti_alias_order must be an integer in [1, 8], got {o!r}")

    @property
    def on(self) -> bool:
        return any(self.accel_mps2) or any(self.gyro_dps)


@dataclass(frozen=True)
class ImuRealism:
    """Inertial sensor errors a flight stack's calibration leaves (standard deviations of the per-run draws)."""

    accel_residual_bias_mg: float | None = 0.0
    """Standard deviation per axis of the accelerometer bias left after a PX4-style calibration [mg]; it replaces
    the part's raw turn-on bias (the datasheet's zero-g offset) in the simulated IMU. 0 (``ideal``): a perfect
    calibration; null: the part's raw turn-on bias as configured (an uncalibrated accelerometer)."""
    scale_factor_ppm: float = 0.0
    """Standard deviation of each axis's scale-factor error, accelerometer and gyroscope [ppm]; added to the part's
    own ``*_scale_factor``."""
    cross_axis_pct: float = 0.0
    """Standard deviation of each off-diagonal element of the sensitivity matrix, both sensors [%]."""
    gyro_g_sensitivity_dps_per_g: float = 0.0
    """Standard deviation of each element of the gyroscope's 3x3 sensitivity to specific force [deg/s per g]."""
    vibration: VibrationRealism = field(default_factory=VibrationRealism)
    """Rotor vibration through the anti-alias filter and the sampling."""
    saturation: bool = False
    """Readings clip at the part's full-scale ranges (``ImuParams.accel_range``/``gyro_range``, the datasheet's)."""

    def __post_init__(self) -> None:
        w = "realism.imu"
        if self.accel_residual_bias_mg is not None:
            _real(self, w, "accel_residual_bias_mg", upper=1000.0)
        _real(self, w, "scale_factor_ppm", upper=1e5)
        _real(self, w, "cross_axis_pct", upper=10.0)
        _real(self, w, "gyro_g_sensitivity_dps_per_g", upper=10.0)
        object.__setattr__(self, "vibration", nested(VibrationRealism, self.vibration, f"{w}.vibration"))
        if not isinstance(self.saturation, bool):
            raise ConfigError(f"{w}.saturation must be true or false, got {self.saturation!r}")


@dataclass(frozen=True)
class LidarRealism:
    """LiDAR range-model terms, passed to the simulated LiDAR's :class:`cufund.sensors.LidarParams` (same names)."""

    range_noise_per_m: float = 0.0
    """Range noise growing with range: sigma(r) = range_noise_std + range_noise_per_m r [m/m]."""
    incidence_noise: float = 0.0
    """Range noise growing with incidence: sigma x (1 + incidence_noise (1 / cos theta - 1)) [-]."""
    max_range_at_10pct: float = math.inf
    """Detection range on a 10 % reflective target at normal incidence [m] (reflectivity- and incidence-dependent
    dropouts); .inf: every return within range_max is detected."""
    detection_softness: float = 0.1
    """Relative width of the fall of the detection probability past the detection range [-]."""
    mixed_pixel_probability: float = 0.0
    """Probability that a return at a depth edge lands between the two surfaces [-]."""
    mixed_pixel_edge_m: float = 0.3
    """Depth jump between neighbouring rays of one channel that makes a depth edge [m]."""
    timestamp_jitter_s: float = 0.0
    """1 sigma noise on each point's reported time offset [s]."""
    intensity_noise: float = 0.0
    """Relative 1 sigma noise on the reported intensity [-]."""

    def __post_init__(self) -> None:
        w = "realism.lidar"
        _real(self, w, "range_noise_per_m", upper=1.0)
        _real(self, w, "incidence_noise", upper=100.0)
        _real(self, w, "max_range_at_10pct", lower=1e-3, inf_ok=True)
        _real(self, w, "detection_softness", upper=10.0)
        _real(self, w, "mixed_pixel_probability", upper=1.0)
        _real(self, w, "mixed_pixel_edge_m", lower=1e-3, upper=100.0)
        _real(self, w, "timestamp_jitter_s", upper=1.0)
        _real(self, w, "intensity_noise", upper=10.0)

    @property
    def on(self) -> bool:
        return self != LidarRealism()


@dataclass(frozen=True)
class CalibrationRealism:
    """How far the extrinsics and clock offsets flight software is given are from the simulated ones."""

    extrinsic_translation_m: float = 0.0
    """Standard deviation per body axis of each mounted sensor's position error [m] (not the IMU's: the body frame
    is the IMU's)."""
    extrinsic_rotation_deg: float = 0.0
    """Standard deviation per body axis of each mounted sensor's rotation error [deg]."""
    lidar_time_offset_s: float = 0.0
    """Standard deviation of each LiDAR's clock offset to the IMU (its stamps minus the true firing times) [s]."""

    def __post_init__(self) -> None:
        w = "realism.calibration"
        _real(self, w, "extrinsic_translation_m", upper=1.0)
        _real(self, w, "extrinsic_rotation_deg", upper=30.0)
        _real(self, w, "lidar_time_offset_s", upper=1.0)


@dataclass(frozen=True)
class VehicleRealism:
    """The simulated plant against the controller's model, and the pad it starts from (uniform draws)."""

    pad_tilt_max_deg: float = 0.0
    """Largest tilt of the take-off pad [deg]: direction uniform, magnitude uniform in [0, this]."""
    mass_pct: float = 0.0
    """Mass error bound [%]: the simulated mass is nominal x (1 + U(-b, b))."""
    inertia_pct: float = 0.0
    """Inertia error bound per principal axis [%] (J' = S^1/2 J S^1/2, S diagonal: J' stays positive definite)."""
    thrust_constant_pct: float = 0.0
    """Thrust coefficient k_f error bound [%]."""
    torque_constant_pct: float = 0.0
    """Rotor drag-torque coefficient k_m = c_m k_f error bound [%] (drawn apart from k_f)."""
    motor_time_constant_pct: float = 0.0
    """Motor time constant tau_m error bound [%]."""

    def __post_init__(self) -> None:
        w = "realism.vehicle"
        _real(self, w, "pad_tilt_max_deg", upper=30.0)
        for name in ("mass_pct", "inertia_pct", "thrust_constant_pct", "torque_constant_pct"):
            _real(self, w, name, upper=50.0)
        _real(self, w, "motor_time_constant_pct", upper=90.0)


PROFILES = ("ideal", "realistic")
_SECTIONS = {
    "imu": ImuRealism,
    "lidar": LidarRealism,
    "calibration": CalibrationRealism,
    "vehicle": VehicleRealism,
}


def _realistic_sections() -> dict[str, Any]:
    """The ``realistic`` profile's values; each is derived, with its source, in docs/realism.md."""
    return {
        "imu": ImuRealism(
            accel_residual_bias_mg=3.0,  # ICM-42688-P zero-g drift 0.15 mg/K over a 20 K change since calibration
            scale_factor_ppm=2500.0,  # ICM-42688-P sensitivity tolerance +-0.5 % read as 2 sigma
            cross_axis_pct=0.5,  # ICM-42688-P cross-axis sensitivity +-1 % read as 2 sigma
            gyro_g_sensitivity_dps_per_g=0.05,  # BMI088 g-sensitivity 0.1 deg/s/g read as 2 sigma
            saturation=True,  # full scale: ICM-42688-P +-16 g / +-2000 deg/s (DS-000347), BMI088 +-24 g / +-2000 deg/s
            vibration=VibrationRealism(
                accel_mps2=(1.0, 1.0, 2.0),
                gyro_dps=(0.3, 0.3, 0.2),
                harmonics=(1.0, 0.3),
                speed_spread=0.02,
                anti_alias_hz=100.0,
                anti_alias_order=2,
            ),
        ),
        "lidar": LidarRealism(
            range_noise_per_m=0.0005,  # with the Mid-360 kind's 2 cm: 2.5 cm at 10 m (datasheet <= 2 cm): pessimistic
            incidence_noise=0.2,  # Assumption: sigma x1.2 at 60 deg, x1.5 at 73 deg
            max_range_at_10pct=40.0,  # Mid-360: 40 m @ 10 % reflectivity
            detection_softness=0.1,
            mixed_pixel_probability=0.1,  # Assumption: one edge return in ten lands between the surfaces
            mixed_pixel_edge_m=0.3,
            timestamp_jitter_s=1e-6,
            intensity_noise=0.05,
        ),
        "calibration": CalibrationRealism(
            extrinsic_translation_m=0.005, extrinsic_rotation_deg=0.3, lidar_time_offset_s=0.002
        ),
        "vehicle": VehicleRealism(
            pad_tilt_max_deg=3.0,
            mass_pct=5.0,
            inertia_pct=10.0,
            thrust_constant_pct=5.0,
            torque_constant_pct=5.0,
            motor_time_constant_pct=20.0,
        ),
    }


def _preset(profile: str) -> dict[str, Any]:
    if profile == "realistic":
        return _realistic_sections()
    return {name: cls() for name, cls in _SECTIONS.items()}


@dataclass(frozen=True)
class RealismConfig:
    """The scenario's ``realism``: a profile (``ideal`` or ``realistic``) and its four sections, any field of which
    a mapping may override. Build one with :meth:`parse`."""

    profile: str = "ideal"
    """``ideal``: every term off, perfect calibration, the exact plant; ``realistic``: see docs/realism.md."""
    imu: ImuRealism = field(default_factory=ImuRealism)
    lidar: LidarRealism = field(default_factory=LidarRealism)
    calibration: CalibrationRealism = field(default_factory=CalibrationRealism)
    vehicle: VehicleRealism = field(default_factory=VehicleRealism)

    def __post_init__(self) -> None:
        if self.profile not in PROFILES:
            raise ConfigError(f"realism.profile must be one of {', '.join(PROFILES)}, got {self.profile!r}")
        for name, cls in _SECTIONS.items():
            if not isinstance(getattr(self, name), cls):
                raise ConfigError(f"realism.{name} must be a {cls.__name__}; build a RealismConfig with parse()")

    @classmethod
    def parse(cls, value: Any) -> RealismConfig:
        """From YAML: null (``ideal``), a profile name, a RealismConfig, or a mapping ``{profile: ..., imu: {...},
        ...}`` whose sections override the profile's values field by field (nested ``vibration`` too)."""
        if value is None:
            return cls()
        if isinstance(value, RealismConfig):
            return value
        if isinstance(value, str):
            value = {"profile": value}
        if not isinstance(value, dict):
            raise ConfigError(
                f"realism must be a profile name ({', '.join(PROFILES)}) or a mapping {{profile: ..., imu: ..., "
                f"lidar: ..., calibration: ..., vehicle: ...}}, got {type(value).__name__}"
            )
        unknown = sorted(set(value) - {"profile", *_SECTIONS}, key=str)
        if unknown:
            raise ConfigError(
                f"unknown key {unknown[0]!r} in realism; expected one of: profile, {', '.join(_SECTIONS)}"
            )
        profile = value.get("profile", "ideal")
        if profile not in PROFILES:
            raise ConfigError(f"realism.profile must be one of {', '.join(PROFILES)}, got {profile!r}")
        sections = _preset(profile)
        for name, cls_ in _SECTIONS.items():
            given = value.get(name)
            if given is None:
                continue
            if not isinstance(given, dict):
                raise ConfigError(f"realism.{name} must be a mapping of field names to values, got {given!r}")
            sections[name] = _override(cls_, sections[name], given, f"realism.{name}")
        return cls(profile, **sections)

    def to_data(self) -> Any:
        """Plain data that :meth:`parse` turns back into an equal config: the profile name alone, or the profile
        and the fields that differ from it."""
        base = _preset(self.profile)
        out: dict[str, Any] = {}
        for name in _SECTIONS:
            diff = _diff(getattr(self, name), base[name])
            if diff:
                out[name] = diff
        return {"profile": self.profile, **out} if out else self.profile


def _override(cls: type, base: Any, given: dict[str, Any], where: str) -> Any:
    names = [f.name for f in dataclasses.fields(cls)]
    unknown = sorted(set(given) - set(names), key=str)
    if unknown:
        raise ConfigError(f"unknown key {unknown[0]!r} in {where}; expected one of: {', '.join(names)}")
    changes = dict(given)
    if "vibration" in changes and isinstance(changes["vibration"], dict):
        changes["vibration"] = _override(VibrationRealism, base.vibration, changes["vibration"], f"{where}.vibration")
    data = {f.name: getattr(base, f.name) for f in dataclasses.fields(cls)}
    data.update(changes)
    return from_dict(cls, data, where)


def _diff(value: Any, base: Any) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for f in dataclasses.fields(value):
        v, b = getattr(value, f.name), getattr(base, f.name)
        if dataclasses.is_dataclass(v):
            d = _diff(v, b)
            if d:
                out[f.name] = d
        elif v != b:
            out[f.name] = list(v) if isinstance(v, tuple) else v
    return out


# ---------------------------------------------------------------------------------------------------------------
# The per-run draws


def _rotvec_q(r: np.ndarray) -> tuple[float, float, float, float]:
    w, x, y, z = quat_from_rotvec(r).tolist()
    return (w, x, y, z)


@dataclass(frozen=True)
class ImuErrors:
    """One IMU's drawn errors (the fields of :class:`cufund.sensors.ImuParams` they go to)."""

    accel_scale_factor: tuple[float, ...]
    gyro_scale_factor: tuple[float, ...]
    accel_cross_axis: tuple[float, ...]
    gyro_cross_axis: tuple[float, ...]
    gyro_g_sensitivity: tuple[float, ...]
    """[rad/s per m/s^2], 3x3 row-major."""


@dataclass(frozen=True)
class MountingErrors:
    """One mounted sensor's drawn calibration error: its true pose is the stated one moved by ``dp_B`` and rotated
    by ``dtheta_B`` (a rotation vector, body axes); a LiDAR's clock offset."""

    dp_B: tuple[float, float, float]
    """[m]"""
    dtheta_B: tuple[float, float, float]
    """[rad]"""
    time_offset_s: float
    """[s] (LiDARs only; 0 otherwise)."""


@dataclass(frozen=True)
class PlantErrors:
    """The drawn plant: scale factors on the nominal parameters and the pad's tilt."""

    mass_scale: float
    inertia_scale: tuple[float, float, float]
    thrust_constant_scale: float
    torque_constant_scale: float
    motor_time_constant_scale: float
    pad_tilt_deg: float
    pad_tilt_direction_deg: float
    """Azimuth (from world x, counter-clockwise) of the pad's downhill direction [deg]."""

    @property
    def q_W_pad(self) -> tuple[float, float, float, float]:
        """The pad's attitude [w, x, y, z]: a rotation by ``pad_tilt_deg`` about the horizontal axis perpendicular
        to the tilt direction."""
        a = math.radians(self.pad_tilt_direction_deg)
        axis = np.array([-math.sin(a), math.cos(a), 0.0])  # tilting about it lowers the pad's +direction side
        return _rotvec_q(axis * math.radians(self.pad_tilt_deg))


_EXACT_PLANT = PlantErrors(1.0, (1.0, 1.0, 1.0), 1.0, 1.0, 1.0, 0.0, 0.0)


@dataclass(frozen=True)
class Realism:
    """A scenario's resolved profile (``ctx.realism``): the config and the errors drawn for this run, and the
    helpers that give the *simulated* parts the perturbed truth. Flight software reads none of this."""

    config: RealismConfig
    imu_errors: Mapping[str, ImuErrors]
    """Per IMU sensor name."""
    mounting_errors: Mapping[str, MountingErrors]
    """Per mounted sensor name (IMUs excluded: the body frame is the IMU's)."""
    plant: PlantErrors

    @property
    def profile(self) -> str:
        return self.config.profile

    @property
    def imu(self) -> ImuRealism:
        return self.config.imu

    @property
    def lidar(self) -> LidarRealism:
        return self.config.lidar

    @property
    def calibration(self) -> CalibrationRealism:
        return self.config.calibration

    @property
    def vehicle(self) -> VehicleRealism:
        return self.config.vehicle

    # -- what the simulated parts get -----------------------------------------------------------------------------

    def simulated_imu(self, where: str, params: Any, hover_rotor_speed: float) -> Any:
        """The simulated IMU's :class:`~cufund.sensors.ImuParams` for the sensor at ``where`` (``sensors.imu``):
        ``params`` (the part as configured) with the residual accelerometer bias, the drawn scale factors,
        cross-axis terms and g-sensitivity, and the vibration (at the simulated vehicle's ``hover_rotor_speed``
        [rad/s])."""
        from cufund.sensors.calibration import after_calibration

        cfg = self.config.imu
        if cfg.accel_residual_bias_mg is not None:
            params = after_calibration(params, cfg.accel_residual_bias_mg * 1e-3 * G0)
        err = self.imu_errors.get(_name(where))
        changes: dict[str, Any] = {}
        if cfg.vibration.on:  # drawn from no stream here: its phases come from the IMU model's own seed
            changes["vibration"] = _vibration_spec(cfg.vibration, hover_rotor_speed, where)
        if err is not None and cfg.scale_factor_ppm:
            changes["accel_scale_factor"] = tuple(
                a + b for a, b in zip(params.accel_scale_factor, err.accel_scale_factor, strict=True)
            )
            changes["gyro_scale_factor"] = tuple(
                a + b for a, b in zip(params.gyro_scale_factor, err.gyro_scale_factor, strict=True)
            )
        if err is not None and cfg.cross_axis_pct:
            changes["accel_cross_axis"] = err.accel_cross_axis
            changes["gyro_cross_axis"] = err.gyro_cross_axis
        if err is not None and cfg.gyro_g_sensitivity_dps_per_g:
            changes["gyro_g_sensitivity"] = err.gyro_g_sensitivity
        if cfg.saturation:
            changes["saturation"] = True
        missing = sorted(set(changes) - {f.name for f in dataclasses.fields(params)})
        if missing:
            raise ConfigError(
                f"{where}: realism.imu needs ImuParams.{missing[0]}, which this IMU model does not have; set the "
                "matching realism.imu field to 0"
            )
        return dataclasses.replace(params, **changes) if changes else params

    def simulated_lidar(self, where: str, params: Any) -> Any:
        """The simulated LiDAR's :class:`~cufund.sensors.LidarParams`: ``params`` with the profile's range-model
        terms and the drawn clock offset of the sensor at ``where``."""
        changes: dict[str, Any] = {}
        if self.config.lidar.on:
            changes.update(dataclasses.asdict(self.config.lidar))
        m = self.mounting_errors.get(_name(where))
        if m is not None and m.time_offset_s:
            changes["time_offset_s"] = m.time_offset_s
        if not changes:
            return params
        names = {f.name for f in dataclasses.fields(params)}
        missing = sorted(set(changes) - names)
        if missing:
            raise ConfigError(
                f"{where}: realism needs LidarParams.{missing[0]}, which this LiDAR model does not have; set the "
                "matching realism.lidar / realism.calibration field to its ideal value"
            )
        return dataclasses.replace(params, **changes)

    def simulated_extrinsic(self, where: str, T_stated: Any) -> Any:
        """The true mounting of the sensor at ``where`` given its stated one (a :class:`cufund.geometry.Transform`
        from the sensor frame to the body): moved by the drawn ``dp_B`` and rotated by ``dtheta_B`` about body axes.
        ``T_stated`` itself when there is no error (or no extrinsic)."""
        m = self.mounting_errors.get(_name(where))
        if m is None or (not any(m.dp_B) and not any(m.dtheta_B)):
            return T_stated
        from cufund.geometry import Transform, quat_mul

        T_stated = T_stated if T_stated is not None else Transform()  # stated: at the body origin
        q = quat_mul(np.asarray(_rotvec_q(np.asarray(m.dtheta_B))), np.asarray(T_stated.q))
        p = np.asarray(T_stated.t) + np.asarray(m.dp_B)
        return Transform((float(p[0]), float(p[1]), float(p[2])), (float(q[0]), float(q[1]), float(q[2]), float(q[3])))

    def simulated_vehicle(self, nominal: Any) -> Any:
        """The simulated plant's :class:`~cufund.vehicle.QuadrotorParams` (``nominal`` itself when the plant is
        exact): the drawn mass, inertia, thrust and torque coefficients and motor lag, resting on the drawn pad tilt
        (``ground_attitude``; :func:`cufund.scenarios.build.build_simulation` starts it there)."""
        e = self.plant
        if e == _EXACT_PLANT:
            return nominal
        s = np.sqrt(np.asarray(e.inertia_scale))
        J = np.asarray(nominal.inertia, dtype=float) * np.outer(s, s)
        k_f = nominal.k_f * e.thrust_constant_scale
        return dataclasses.replace(
            nominal,
            mass=nominal.mass * e.mass_scale,
            inertia=tuple(tuple(float(x) for x in row) for row in J),
            k_f=k_f,
            c_m=nominal.c_m * e.torque_constant_scale / e.thrust_constant_scale,  # k_m = c_m k_f scaled on its own
            tau_m=nominal.tau_m * e.motor_time_constant_scale,
            ground_attitude=e.q_W_pad if e.pad_tilt_deg else nominal.ground_attitude,  # rests on the tilted pad
        )

    def summary(self) -> dict[str, Any]:
        """What metrics.json records: the profile (as given) and every drawn value."""
        e = self.plant
        out: dict[str, Any] = {
            "profile": self.profile,
            "config": self.config.to_data(),
            "pad_tilt_deg": e.pad_tilt_deg,
            "pad_tilt_direction_deg": e.pad_tilt_direction_deg,
            "mass_scale": e.mass_scale,
            "inertia_scale": list(e.inertia_scale),
            "thrust_constant_scale": e.thrust_constant_scale,
            "torque_constant_scale": e.torque_constant_scale,
            "motor_time_constant_scale": e.motor_time_constant_scale,
        }
        for name, m in self.mounting_errors.items():
            out[f"extrinsic_error_{name}"] = {
                "dp_B_m": list(m.dp_B),
                "dtheta_B_deg": [math.degrees(v) for v in m.dtheta_B],
                "translation_m": float(np.linalg.norm(m.dp_B)),
                "rotation_deg": math.degrees(float(np.linalg.norm(m.dtheta_B))),
            }
            if m.time_offset_s:
                out[f"{name}_time_offset_s"] = m.time_offset_s
        lidars = [n for n, m in self.mounting_errors.items() if m.time_offset_s]
        if len(lidars) == 1:
            out["lidar_time_offset_s"] = self.mounting_errors[lidars[0]].time_offset_s
        for name, err in self.imu_errors.items():
            out[f"imu_errors_{name}"] = {f.name: list(getattr(err, f.name)) for f in dataclasses.fields(err)}
        return out


def _name(where: str) -> str:
    return where.split(".", 1)[1] if where.startswith("sensors.") else where


def _vibration_spec(v: VibrationRealism, hover_rotor_speed: float, where: str) -> Any:
    try:
        from cufund.sensors.imu_vibration import VibrationSpec  # type: ignore[import-not-found,unused-ignore]
    except ImportError:
        raise ConfigError(
            f"{where}: realism.imu.vibration needs the IMU vibration model (cufund.sensors.imu_vibration); set "
            "realism.imu.vibration.accel_mps2 and gyro_dps to 0"
        ) from None
    return VibrationSpec(
        accel_mps2=v.accel_mps2,
        gyro_radps=(v.gyro_dps[0] * DEG, v.gyro_dps[1] * DEG, v.gyro_dps[2] * DEG),
        harmonics=v.harmonics,
        speed_spread=v.speed_spread,
        hover_rotor_speed=float(hover_rotor_speed),
        anti_alias_hz=v.anti_alias_hz,
        anti_alias_order=v.anti_alias_order,
    )


def resolve(config: RealismConfig, sensors: Mapping[str, Any], seed_for: Callable[[str], int]) -> Realism:
    """Draws this run's errors for ``config`` from the scenario's streams ``seed_for("realism.<section>...")``:
    one stream per IMU (``realism.imu.<name>``), per mounted sensor (``realism.calibration.<name>``) and for the
    plant (``realism.vehicle``), so adding a sensor changes no other draw. ``sensors``: the scenario's parsed
    sensors (name -> :class:`~cufund.scenarios.schema.PartSpec`)."""
    imu_cfg, cal, veh = config.imu, config.calibration, config.vehicle
    imu_errors: dict[str, ImuErrors] = {}
    mounting: dict[str, MountingErrors] = {}
    for name, spec in sensors.items():
        if spec.sensor_type == "imu":
            if imu_cfg.scale_factor_ppm or imu_cfg.cross_axis_pct or imu_cfg.gyro_g_sensitivity_dps_per_g:
                rng = np.random.default_rng(seed_for(f"realism.imu.{name}"))
                sf = rng.standard_normal(6) * imu_cfg.scale_factor_ppm * 1e-6
                ca = rng.standard_normal(12) * imu_cfg.cross_axis_pct * 1e-2
                gs = rng.standard_normal(9) * imu_cfg.gyro_g_sensitivity_dps_per_g * DEG / G0
                imu_errors[name] = ImuErrors(
                    tuple(float(x) for x in sf[:3]),
                    tuple(float(x) for x in sf[3:]),
                    tuple(float(x) for x in ca[:6]),
                    tuple(float(x) for x in ca[6:]),
                    tuple(float(x) for x in gs),
                )
            continue
        is_lidar = spec.sensor_type == "lidar"
        mounted = spec.extrinsic is not None or _has_extrinsic_key(spec)
        if not (mounted or is_lidar):
            continue
        if not (cal.extrinsic_translation_m or cal.extrinsic_rotation_deg or (is_lidar and cal.lidar_time_offset_s)):
            continue
        rng = np.random.default_rng(seed_for(f"realism.calibration.{name}"))
        dp = rng.standard_normal(3) * cal.extrinsic_translation_m if mounted else np.zeros(3)
        dth = rng.standard_normal(3) * math.radians(cal.extrinsic_rotation_deg) if mounted else np.zeros(3)
        dt = float(rng.standard_normal() * cal.lidar_time_offset_s) if is_lidar else 0.0
        mounting[name] = MountingErrors(
            (float(dp[0]), float(dp[1]), float(dp[2])), (float(dth[0]), float(dth[1]), float(dth[2])), dt
        )
    rng = np.random.default_rng(seed_for("realism.vehicle"))
    u = rng.uniform(-1.0, 1.0, 7)
    tilt = rng.uniform(0.0, 1.0, 2)
    plant = PlantErrors(
        mass_scale=1.0 + u[0] * veh.mass_pct / 100,
        inertia_scale=tuple(float(1.0 + x * veh.inertia_pct / 100) for x in u[1:4]),  # type: ignore[arg-type]
        thrust_constant_scale=1.0 + u[4] * veh.thrust_constant_pct / 100,
        torque_constant_scale=1.0 + u[5] * veh.torque_constant_pct / 100,
        motor_time_constant_scale=1.0 + u[6] * veh.motor_time_constant_pct / 100,
        pad_tilt_deg=float(tilt[0] * veh.pad_tilt_max_deg),
        pad_tilt_direction_deg=float(tilt[1] * 360.0) if veh.pad_tilt_max_deg else 0.0,
    )
    return Realism(config, imu_errors, mounting, plant)


def _has_extrinsic_key(spec: Any) -> bool:
    """A sensor of a type with a mounting key (a camera, a LiDAR) mounted at the body origin (no extrinsic given)."""
    from cufund.core.registry import sensor_type

    return spec.sensor_type is not None and sensor_type(spec.sensor_type).extrinsic_key is not None
