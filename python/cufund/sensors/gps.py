"""GNSS receiver: WGS-84 fixes of the local ENU position with noise, random-walk drift, latency and outages.

Each fix is computed from the true position and velocity at its measurement time and delivered
``latency_s`` later (to the resolution of the receiver's rate). Position error per axis (E, N, U) is white
noise of ``horizontal_sigma_m``/``vertical_sigma_m`` per fix plus a random walk (multipath and atmospheric
drift); velocity error is white. During an outage, or with fewer than ``min_satellites`` in view, the
fix has ``fix_type = 0`` and NaN position and velocity.
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass, field

import numpy as np

from cufund.core.config import ConfigError, check_real_fields, nested
from cufund.core.messages import GpsFix, Odometry, Topics

from .geodesy import GeoPoint, enu_to_lla
from .model_sensor import ModelSensor
from .noise import ErrorProcess, NoiseSpec, real_fields

__all__ = ["GpsParams", "GpsFix", "GpsModel", "GpsSensor", "GPS_PRESETS", "CEP_TO_SIGMA"]

CEP_TO_SIGMA = 1.0 / 1.1774  # circular error probable (50 %) of a 2-D Gaussian = 1.1774 sigma


@dataclass(frozen=True)
class GpsParams:
    """A receiver and its environment."""

    rate_hz: float = 10.0
    home: GeoPoint = field(default_factory=lambda: GeoPoint(22.4196, 114.2068, 30.0))
    """Where the world origin is (default: CUHK campus, Hong Kong)."""
    horizontal_sigma_m: float = 0.0
    vertical_sigma_m: float = 0.0
    drift_m_per_sqrt_s: float = 0.0
    """Random-walk drift of each position axis [m/sqrt(s)]."""
    velocity_sigma_m_s: float = 0.0
    latency_s: float = 0.0
    satellites: int = 14
    min_satellites: int = 6
    outages: tuple[tuple[float, float], ...] = ()
    """Intervals [start, end) of simulated time [s] without a fix (e.g. under a bridge)."""
    name: str = "ideal"

    def __post_init__(self) -> None:
        real_fields(self, "GpsParams")
        object.__setattr__(self, "home", nested(GeoPoint, self.home, "GpsParams.home"))
        if not (math.isfinite(self.rate_hz) and 0 < self.rate_hz <= 50):
            raise ConfigError(f"rate_hz must be in (0, 50] [Hz], got {self.rate_hz!r}")
        check_real_fields(
            self,
            "GpsParams",
            names=("horizontal_sigma_m", "vertical_sigma_m", "drift_m_per_sqrt_s", "velocity_sigma_m_s", "latency_s"),
        )
        if not (isinstance(self.satellites, int) and 0 <= self.satellites <= 64):
            raise ConfigError(f"satellites must be an integer in [0, 64], got {self.satellites!r}")
        if not (isinstance(self.min_satellites, int) and 4 <= self.min_satellites):
            raise ConfigError(f"min_satellites must be an integer >= 4, got {self.min_satellites!r}")
        try:
            outages = tuple((float(a), float(b)) for a, b in self.outages)
        except (TypeError, ValueError):
            raise ConfigError(f"outages must be a list of [start, end] pairs [s], got {self.outages!r}") from None
        if any(not (b > a) for a, b in outages):
            raise ConfigError(f"outages must have end > start, got {self.outages!r}")
        object.__setattr__(self, "outages", outages)


#: u-blox NEO-M8N (UBX-15031086 data sheet): horizontal accuracy 2.5 m CEP (GPS & GLONASS), velocity
#: 0.05 m/s, 10 Hz used here (18 Hz max). NEO-M9N (UBX-19014285): 1.5 m CEP, 0.05 m/s, 25 Hz max.
#: Vertical sigma as twice the horizontal (typical of GNSS geometry); drift 0.05 m/sqrt(s) and 0.1 s
#: latency as commonly seen on these receivers (not in the data sheets).
GPS_PRESETS = {
    "ublox_m8n": lambda: GpsParams(
        name="ublox_m8n",
        rate_hz=10.0,
        horizontal_sigma_m=2.5 * CEP_TO_SIGMA,
        vertical_sigma_m=5.0 * CEP_TO_SIGMA,
        drift_m_per_sqrt_s=0.05,
        velocity_sigma_m_s=0.05,
        latency_s=0.1,
    ),
    "ublox_m9n": lambda: GpsParams(
        name="ublox_m9n",
        rate_hz=10.0,
        horizontal_sigma_m=1.5 * CEP_TO_SIGMA,
        vertical_sigma_m=3.0 * CEP_TO_SIGMA,
        drift_m_per_sqrt_s=0.03,
        velocity_sigma_m_s=0.05,
        latency_s=0.1,
    ),
    "ideal": lambda: GpsParams(),
}


class GpsModel:
    """Produces :class:`GpsFix` es from the true ENU position and velocity, from one seeded stream."""

    def __init__(self, params: GpsParams, seed: int = 0) -> None:
        self.params = params
        dt = 1.0 / params.rate_hz
        h, v = params.horizontal_sigma_m, params.vertical_sigma_m
        pos = NoiseSpec((h * math.sqrt(dt), h * math.sqrt(dt), v * math.sqrt(dt)), params.drift_m_per_sqrt_s, 0.0)
        vel = NoiseSpec(params.velocity_sigma_m_s * math.sqrt(dt), 0.0, 0.0)
        self._errors = ErrorProcess([(pos, 3), (vel, 3)], dt, seed)
        self._sat_rng = np.random.default_rng([seed, 1])
        self.reset()

    def reset(self) -> None:
        self._errors.reset()
        self._sat_rng = np.random.default_rng([self._errors.seed, 1])
        self._satellites = self.params.satellites
        self._pending: collections.deque[GpsFix] = collections.deque()

    def _in_outage(self, t: float) -> bool:
        return any(a <= t < b for a, b in self.params.outages)

    def measure(self, t: float, p_W: np.ndarray, v_W: np.ndarray) -> GpsFix | None:
        """Records a measurement of the truth at time t [s]; returns the newest fix whose latency has elapsed
        by t (None while none has)."""
        p_W, v_W = np.asarray(p_W, dtype=float), np.asarray(v_W, dtype=float)
        if p_W.shape != (3,) or v_W.shape != (3,) or not (np.all(np.isfinite(p_W)) and np.all(np.isfinite(v_W))):
            raise ValueError("p_W and v_W must be finite with shape (3,)")
        p = self.params
        e = self._errors.sample(1)[0]
        # Satellites in view: a slow random walk about the nominal count.
        r = self._sat_rng.random()
        if r < 0.05:
            self._satellites = p.satellites
        elif r < 0.15:
            self._satellites = int(np.clip(self._satellites + (1 if r < 0.10 else -1), 0, 64))
        sats = self._satellites if not self._in_outage(t) else int(self._sat_rng.integers(0, 4))
        if sats >= p.min_satellites:
            lat, lon, alt = enu_to_lla(p_W + e[:3], p.home)
            fix = GpsFix(
                t, float(lat), float(lon), float(alt), v_W + e[3:], 3, sats, p.horizontal_sigma_m, p.vertical_sigma_m
            )
        else:
            fix = GpsFix(t, math.nan, math.nan, math.nan, np.full(3, math.nan), 0, sats, math.inf, math.inf)
        self._pending.append(fix)
        ready = None
        while self._pending and self._pending[0].t + p.latency_s <= t + 1e-9:
            ready = self._pending.popleft()
        return ready


class GpsSensor(ModelSensor):
    """Publishes :class:`~cufund.core.messages.GpsFix` es at the receiver's rate, each ``latency_s`` after its
    measurement time (rounded to the receiver's period)."""

    name = "gps"

    def __init__(self, params: GpsParams, seed: int = 0, topic: str = Topics.GPS) -> None:
        super().__init__(GpsModel(params, seed), params.rate_hz, topic)

    def measure(self, t: float, truth: Odometry) -> GpsFix | None:
        return self.model.measure(t, truth.p_W, truth.v_W)
