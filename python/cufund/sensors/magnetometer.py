"""Magnetometer: the Earth's field at home, rotated into the body, with hard/soft iron and the error model.

    m_B = S (R_WB^T B_W) + h + b + n

B_W is the field in world ENU from declination D (east of north), inclination I (positive pointing down)
and total intensity F:  B_W = F [cos I sin D, cos I cos D, -sin I]. ``S`` is the soft-iron matrix,
``h`` the hard-iron offset; ``b`` and ``n`` follow :mod:`cufund.sensors.noise`. Units: tesla.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cufund.core.config import ConfigError, check_at_most, check_real_fields, nested
from cufund.core.messages import MagneticField, Odometry, Topics
from cufund.geometry import quat_to_matrix, world_to_body

from .model_sensor import ModelSensor
from .noise import ErrorProcess, NoiseSpec, real_fields

__all__ = ["EarthField", "MagnetometerParams", "MagnetometerModel", "MagnetometerSensor"]


@dataclass(frozen=True)
class EarthField:
    """The geomagnetic field at the home location (e.g. from the NOAA World Magnetic Model calculator).

    The defaults are rounded WMM values for Hong Kong (22.4 N, 114.2 E), where the paper's work was done:
    declination -3.3 deg, inclination 31 deg, intensity 45 uT."""

    declination_deg: float = -3.3
    inclination_deg: float = 31.0
    intensity_T: float = 45e-6

    def __post_init__(self) -> None:
        real_fields(self, "EarthField")
        if not (math.isfinite(self.declination_deg) and -180 <= self.declination_deg <= 180):
            raise ConfigError(f"declination_deg must be in [-180, 180], got {self.declination_deg!r}")
        if not (math.isfinite(self.inclination_deg) and -90 <= self.inclination_deg <= 90):
            raise ConfigError(f"inclination_deg must be in [-90, 90], got {self.inclination_deg!r}")
        if not (math.isfinite(self.intensity_T) and 0 < self.intensity_T < 1e-3):
            raise ConfigError(f"intensity_T must be in (0, 1e-3) [T] (Earth: 25-65 uT), got {self.intensity_T!r}")

    @property
    def B_W(self) -> np.ndarray:
        """The field in world ENU [T], (3,)."""
        d, i = math.radians(self.declination_deg), math.radians(self.inclination_deg)
        return self.intensity_T * np.array([math.cos(i) * math.sin(d), math.cos(i) * math.cos(d), -math.sin(i)])


@dataclass(frozen=True)
class MagnetometerParams:
    """A magnetometer and its installation. Defaults: 0.3 uT RMS noise at 100 Hz, typical of the
    IST8310/QMC5883L class used on small flight controllers, and a slow 1 nT/s/sqrt(Hz) drift."""

    rate_hz: float = 100.0
    noise: NoiseSpec = field(default_factory=lambda: NoiseSpec(0.3e-6 / math.sqrt(100.0), 1e-9, 0.0))
    """Errors [T/sqrt(Hz)], [T/s/sqrt(Hz)], turn-on bias [T]."""
    hard_iron_T: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Constant offset from magnetised parts of the vehicle [T], body frame."""
    soft_iron: tuple[tuple[float, float, float], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    """Soft-iron distortion matrix S (identity: none)."""
    earth: EarthField = field(default_factory=EarthField)

    def __post_init__(self) -> None:
        real_fields(self, "MagnetometerParams")
        check_real_fields(self, "MagnetometerParams", positive=True, unit=" [Hz]", names=("rate_hz",))
        check_at_most(self, "MagnetometerParams", rate_hz=1e3)
        object.__setattr__(self, "noise", nested(NoiseSpec, self.noise, "MagnetometerParams.noise"))
        object.__setattr__(self, "earth", nested(EarthField, self.earth, "MagnetometerParams.earth"))
        self.noise.per_axis(3)
        h = np.asarray(self.hard_iron_T, dtype=float)
        if h.shape != (3,) or not np.all(np.isfinite(h)):
            raise ConfigError(f"hard_iron_T must be 3 finite numbers [T], got {self.hard_iron_T!r}")
        s = np.asarray(self.soft_iron, dtype=float)
        if s.shape != (3, 3) or not np.all(np.isfinite(s)) or abs(np.linalg.det(s)) < 1e-6:
            raise ConfigError("soft_iron must be an invertible 3x3 matrix of finite numbers")
        object.__setattr__(self, "hard_iron_T", tuple(float(x) for x in h))
        object.__setattr__(self, "soft_iron", tuple(tuple(float(x) for x in row) for row in s))


class MagnetometerModel:
    """Samples of the field in the body frame [T] for attitudes q_WB [w, x, y, z], from one seeded stream."""

    def __init__(self, params: MagnetometerParams, seed: int = 0) -> None:
        self.params = params
        self._errors = ErrorProcess([(params.noise, 3)], 1.0 / params.rate_hz, seed)
        self._S = np.asarray(params.soft_iron)
        self._h = np.asarray(params.hard_iron_T)
        self._B_W = params.earth.B_W
        self._B_W_tuple = tuple(float(v) for v in self._B_W)

    def reset(self) -> None:
        self._errors.reset()

    def measure(self, q_WB: np.ndarray) -> np.ndarray:
        """(K, 3) or (3,) field samples [T] for attitudes (K, 4) or (4,)."""
        if np.shape(q_WB) == (4,):
            qw, qx, qy, qz = (float(v) for v in q_WB)
            if not all(math.isfinite(v) for v in (qw, qx, qy, qz)):
                raise ValueError("q_WB must be finite")
            B_B = np.array(world_to_body(qw, qx, qy, qz, *self._B_W_tuple))  # the per-tick path
            return self._S @ B_B + self._h + self._errors.sample_one()
        q = np.atleast_2d(np.asarray(q_WB, dtype=float))
        if q.ndim != 2 or q.shape[1] != 4 or not np.all(np.isfinite(q)):
            raise ValueError(f"q_WB must be finite with shape (4,) or (K, 4), got {np.shape(q_WB)}")
        B_B = np.einsum("kji,j->ki", quat_to_matrix(q), self._B_W)
        m = B_B @ self._S.T + self._h + self._errors.sample(q.shape[0])
        return m[0] if np.ndim(q_WB) == 1 else m


class MagnetometerSensor(ModelSensor):
    """Publishes :class:`~cufund.core.messages.MagneticField` samples at the sensor's rate."""

    name = "magnetometer"

    def __init__(self, params: MagnetometerParams, seed: int = 0, topic: str = Topics.MAGNETOMETER) -> None:
        super().__init__(MagnetometerModel(params, seed), params.rate_hz, topic)

    def measure(self, t: float, truth: Odometry) -> MagneticField:
        return MagneticField(t, self.model.measure(truth.q_WB))
