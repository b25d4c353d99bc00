"""WGS-84 geodesy: local ENU (the simulator's world frame) <-> latitude, longitude, ellipsoidal height."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.config import ConfigError

__all__ = ["GeoPoint", "WGS84_A", "WGS84_F", "lla_to_ecef", "ecef_to_lla", "enu_to_lla", "lla_to_enu"]

WGS84_A = 6378137.0  # semi-major axis [m]
WGS84_F = 1.0 / 298.257223563  # flattening
_E2 = WGS84_F * (2.0 - WGS84_F)  # first eccentricity squared


@dataclass(frozen=True)
class GeoPoint:
    """A WGS-84 location: latitude and longitude [deg], height above the ellipsoid [m]."""

    latitude_deg: float
    longitude_deg: float
    altitude_m: float = 0.0

    def __post_init__(self) -> None:
        if not (np.isfinite(self.latitude_deg) and -90.0 <= self.latitude_deg <= 90.0):
            raise ConfigError(f"latitude_deg must be in [-90, 90], got {self.latitude_deg!r}")
        if not (np.isfinite(self.longitude_deg) and -180.0 <= self.longitude_deg <= 180.0):
            raise ConfigError(f"longitude_deg must be in [-180, 180], got {self.longitude_deg!r}")
        if not np.isfinite(self.altitude_m):
            raise ConfigError(f"altitude_m must be finite, got {self.altitude_m!r}")


def lla_to_ecef(lat_rad: Any, lon_rad: Any, h: Any) -> np.ndarray:
    """ECEF [m] (..., 3) of geodetic latitude, longitude [rad] and ellipsoidal height [m]."""
    sl, cl = np.sin(lat_rad), np.cos(lat_rad)
    n = WGS84_A / np.sqrt(1.0 - _E2 * sl * sl)  # prime-vertical radius of curvature
    return np.stack([(n + h) * cl * np.cos(lon_rad), (n + h) * cl * np.sin(lon_rad), (n * (1.0 - _E2) + h) * sl], -1)


def ecef_to_lla(xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Geodetic latitude, longitude [rad] and height [m] of ECEF points (..., 3), by fixed-point iteration on
    latitude (converges to well below a micrometre in 6 iterations anywhere near the Earth's surface)."""
    x, y, z = np.moveaxis(np.asarray(xyz, dtype=float), -1, 0)
    lon = np.arctan2(y, x)
    r = np.hypot(x, y)
    lat = np.arctan2(z, r * (1.0 - _E2))
    for _ in range(6):
        sl = np.sin(lat)
        n = WGS84_A / np.sqrt(1.0 - _E2 * sl * sl)
        h = r / np.cos(lat) - n
        lat = np.arctan2(z, r * (1.0 - _E2 * n / (n + h)))
    sl = np.sin(lat)
    n = WGS84_A / np.sqrt(1.0 - _E2 * sl * sl)
    h = r / np.cos(lat) - n
    return lat, lon, h


def _enu_basis(home: GeoPoint) -> tuple[np.ndarray, np.ndarray]:
    lat, lon = np.radians(home.latitude_deg), np.radians(home.longitude_deg)
    origin = lla_to_ecef(lat, lon, home.altitude_m)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    R_ecef_enu = np.array([[-so, -sl * co, cl * co], [co, -sl * so, cl * so], [0.0, cl, sl]])  # columns: E, N, U
    return origin, R_ecef_enu


def enu_to_lla(p_W: np.ndarray, home: GeoPoint) -> np.ndarray:
    """Latitude, longitude [deg], height [m] (..., 3) of local ENU positions p_W (..., 3) [m] about ``home``."""
    origin, R = _enu_basis(home)
    lat, lon, h = ecef_to_lla(origin + np.asarray(p_W, dtype=float) @ R.T)
    return np.stack([np.degrees(lat), np.degrees(lon), h], -1)


def lla_to_enu(lla: np.ndarray, home: GeoPoint) -> np.ndarray:
    """Local ENU positions [m] (..., 3) of latitude, longitude [deg], height [m] (..., 3) about ``home``."""
    lla = np.asarray(lla, dtype=float)
    origin, R = _enu_basis(home)
    ecef = lla_to_ecef(np.radians(lla[..., 0]), np.radians(lla[..., 1]), lla[..., 2])
    return (ecef - origin) @ R
