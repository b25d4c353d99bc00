"""The one place where cufund's frames meet PX4's / MAVLink's: ENU <-> NED, FLU <-> FRD, attitude quaternions,
geodetic positions and MAVLink's integer encodings. Nothing else in cufund converts frames for MAVLink.

cufund: world ENU (x east, y north, z up), body FLU (x forward, y left, z up), quaternions ``[w, x, y, z]`` with
``q_WB`` rotating body vectors into the world. PX4 / MAVLink: local NED (x north, y east, z down), body FRD
(x forward, y right, z down), attitude quaternion ``[w, x, y, z]`` rotating FRD vectors into NED (PX4's
``vehicle_attitude.q``, MAVLink ``HIL_STATE_QUATERNION.attitude_quaternion``).

Every function is vectorised: vectors (..., 3), quaternions (..., 4). Both axis changes are proper rotations by
180 degrees (ENU->NED about (1, 1, 0)/sqrt(2), FLU->FRD about x), so each is its own inverse and angular rates,
magnetic fields and specific forces transform exactly like positions.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.sensors.geodesy import GeoPoint, enu_to_lla, lla_to_enu

__all__ = [
    "INT16_MAX",
    "STANDARD_GRAVITY",
    "UINT16_UNKNOWN",
    "GeodeticOrigin",
    "cm_s_to_m_s",
    "course_cdeg",
    "deg_to_e7",
    "e7_to_deg",
    "enu_to_ned",
    "flu_to_frd",
    "flu_to_frd_xyz",
    "frd_to_flu",
    "m_s2_to_mg",
    "m_s_to_cm_s",
    "m_to_cm_u16",
    "m_to_mm",
    "mg_to_m_s2",
    "mm_to_m",
    "ned_to_enu",
    "q_enu_flu_to_ned_frd",
    "q_ned_frd_to_enu_flu",
    "rates_flu_to_frd",
    "rates_frd_to_flu",
    "yaw_enu_to_ned",
    "yaw_ned_to_enu",
]

STANDARD_GRAVITY = 9.80665  #: g0 [m/s^2] (MAVLink's milli-g unit)
INT16_MAX = 32767
UINT16_UNKNOWN = 65535  #: MAVLink's "unknown" for uint16 fields (eph, epv, vel, cog)

_SQRT_HALF = float(np.sqrt(0.5))
_SWAP_XY = [1, 0, 2]
_FLIP_Z = np.array([1.0, 1.0, -1.0])  # multiplying by +-1 is exact: these are pure axis relabellings
_FLIP_YZ = np.array([1.0, -1.0, -1.0])
_FLIP_Z.setflags(write=False)
_FLIP_YZ.setflags(write=False)


def _vec3(v: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.ndim == 0 or a.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (..., 3), got {a.shape}")
    return a


def _quat(q: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(q, dtype=float)
    if a.ndim == 0 or a.shape[-1] != 4:
        raise ValueError(f"{name} must have shape (..., 4) as [w, x, y, z], got {a.shape}")
    return a


def enu_to_ned(v_ENU: np.ndarray) -> np.ndarray:
    """World vectors (..., 3) ENU -> NED: (x, y, z) -> (y, x, -z). Positions, velocities, accelerations, rates."""
    return _vec3(v_ENU, "v_ENU")[..., _SWAP_XY] * _FLIP_Z


def ned_to_enu(v_NED: np.ndarray) -> np.ndarray:
    """World vectors (..., 3) NED -> ENU: (x, y, z) -> (y, x, -z) (the same swap; it is its own inverse)."""
    return _vec3(v_NED, "v_NED")[..., _SWAP_XY] * _FLIP_Z


def flu_to_frd(v_FLU: np.ndarray) -> np.ndarray:
    """Body vectors (..., 3) FLU -> FRD: (x, y, z) -> (x, -y, -z). Specific force, magnetic field, velocity."""
    return _vec3(v_FLU, "v_FLU") * _FLIP_YZ


def flu_to_frd_xyz(x: float, y: float, z: float) -> tuple[float, float, float]:
    """:func:`flu_to_frd` of one vector as three plain floats (the per-period hot path, no arrays)."""
    return x, -y, -z


def frd_to_flu(v_FRD: np.ndarray) -> np.ndarray:
    """Body vectors (..., 3) FRD -> FLU: (x, y, z) -> (x, -y, -z)."""
    return _vec3(v_FRD, "v_FRD") * _FLIP_YZ


def rates_flu_to_frd(w_FLU: np.ndarray) -> np.ndarray:
    """Body angular rates (..., 3) [rad/s] FLU -> FRD (roll rate kept; pitch and yaw rate change sign, as the
    axes do: a proper rotation maps the pseudo-vector like any vector)."""
    return flu_to_frd(_vec3(w_FLU, "w_FLU"))


def rates_frd_to_flu(w_FRD: np.ndarray) -> np.ndarray:
    """Body angular rates (..., 3) [rad/s] FRD -> FLU."""
    return frd_to_flu(_vec3(w_FRD, "w_FRD"))


def q_enu_flu_to_ned_frd(q_WB: np.ndarray) -> np.ndarray:
    """PX4 attitude q_NED_FRD (..., 4) [w, x, y, z] of cufund's q_WB (ENU world, FLU body).

    q_NED_FRD = q_NED_ENU * q_WB * q_FLU_FRD with q_NED_ENU = (0, 1, 1, 0)/sqrt(2) and q_FLU_FRD = (0, 1, 0, 0);
    expanded (and negated, the same rotation): sqrt(1/2) * (w + z, x + y, x - y, w - z). Identity q_WB (nose
    east) gives yaw +90 degrees in NED.
    """
    q = _quat(q_WB, "q_WB")
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return _SQRT_HALF * np.stack([w + z, x + y, x - y, w - z], -1)


def q_ned_frd_to_enu_flu(q_NED_FRD: np.ndarray) -> np.ndarray:
    """cufund q_WB (ENU world, FLU body) (..., 4) of a PX4 attitude q_NED_FRD (the same map: it is an involution)."""
    q = _quat(q_NED_FRD, "q_NED_FRD")
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return _SQRT_HALF * np.stack([w + z, x + y, x - y, w - z], -1)


def yaw_enu_to_ned(yaw_ENU: Any) -> Any:  # a scalar for a scalar, an array for an array
    """Heading [rad] of a body x axis: cufund's yaw (from east, counter-clockwise) -> NED yaw (from north,
    clockwise), wrapped to [-pi, pi)."""
    out = (np.pi / 2 - np.asarray(yaw_ENU, dtype=float) + np.pi) % (2 * np.pi) - np.pi
    return float(out) if out.ndim == 0 else out


def yaw_ned_to_enu(yaw_NED: Any) -> Any:  # a scalar for a scalar, an array for an array
    """NED yaw [rad] -> cufund yaw, wrapped to [-pi, pi) (the same reflection: its own inverse)."""
    return yaw_enu_to_ned(yaw_NED)


@dataclass(frozen=True)
class GeodeticOrigin:
    """The WGS-84 point where cufund's world origin sits (PX4's home / local-position reference).

    Uses cufund's GPS-sensor projection (:mod:`cufund.sensors.geodesy`, exact WGS-84 ENU tangent frame), so a
    position reported through MAVLink and a ``GpsFix`` from the GPS sensor agree. ``alt_m`` is used as
    MAVLink's AMSL altitude (no geoid model: ellipsoid height == AMSL here).
    """

    lat_deg: float  #: latitude [deg], in [-90, 90]
    lon_deg: float  #: longitude [deg], in [-180, 180]
    alt_m: float = 0.0  #: altitude of the world origin [m]

    def __post_init__(self) -> None:
        GeoPoint(float(self.lat_deg), float(self.lon_deg), float(self.alt_m))  # ConfigError naming the field

    @property
    def geo_point(self) -> GeoPoint:
        return GeoPoint(float(self.lat_deg), float(self.lon_deg), float(self.alt_m))

    @classmethod
    def from_geo_point(cls, home: GeoPoint) -> GeodeticOrigin:
        return cls(home.latitude_deg, home.longitude_deg, home.altitude_m)

    def enu_to_lla(self, p_W: np.ndarray) -> np.ndarray:
        """(lat [deg], lon [deg], alt [m]) (..., 3) of world ENU positions (..., 3) [m]."""
        return enu_to_lla(_vec3(p_W, "p_W"), self.geo_point)

    def lla_to_enu(self, lla: np.ndarray) -> np.ndarray:
        """World ENU positions (..., 3) [m] of (lat [deg], lon [deg], alt [m]) (..., 3)."""
        return lla_to_enu(_vec3(lla, "lla"), self.geo_point)

    def ned_to_lla(self, p_NED: np.ndarray) -> np.ndarray:
        """(lat, lon, alt) (..., 3) of local NED positions (..., 3) [m] about this origin."""
        return self.enu_to_lla(ned_to_enu(_vec3(p_NED, "p_NED")))

    def lla_to_ned(self, lla: np.ndarray) -> np.ndarray:
        """Local NED positions (..., 3) [m] of (lat, lon, alt) (..., 3)."""
        return enu_to_ned(self.lla_to_enu(lla))


# --- MAVLink integer encodings: round to nearest, saturate to the field's range; 0-d in -> Python int out ---


def _encode(x: Any, scale: float, lo: int, hi: int, name: str) -> Any:  # scalar in, scalar out
    a = np.asarray(x, dtype=float)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {x!r}")
    out = np.clip(np.rint(a * scale), lo, hi).astype(np.int64)
    return int(out) if out.ndim == 0 else out


def _decode(x: Any, scale: float) -> Any:  # a scalar for a scalar, an array for an array
    out = np.asarray(x, dtype=float) / scale
    return float(out) if out.ndim == 0 else out


def deg_to_e7(deg: Any) -> Any:  # a scalar for a scalar, an array for an array
    """Degrees -> degE7 (int32), MAVLink's lat/lon encoding."""
    return _encode(deg, 1e7, -(2**31), 2**31 - 1, "deg")


def e7_to_deg(e7: Any) -> Any:  # a scalar for a scalar, an array for an array
    return _decode(e7, 1e7)


def m_to_mm(m: Any) -> Any:  # a scalar for a scalar, an array for an array
    """Metres -> millimetres (int32), MAVLink's altitude encoding."""
    return _encode(m, 1e3, -(2**31), 2**31 - 1, "m")


def mm_to_m(mm: Any) -> Any:  # a scalar for a scalar, an array for an array
    return _decode(mm, 1e3)


def m_s_to_cm_s(v: Any) -> Any:  # a scalar for a scalar, an array for an array
    """m/s -> cm/s (int16, saturated at +-32767), HIL_GPS vn/ve/vd and HIL_STATE_QUATERNION vx/vy/vz."""
    return _encode(v, 1e2, -INT16_MAX, INT16_MAX, "v")


def cm_s_to_m_s(cm_s: Any) -> Any:  # a scalar for a scalar, an array for an array
    return _decode(cm_s, 1e2)


def m_to_cm_u16(m: Any) -> Any:  # a scalar for a scalar, an array for an array
    """Non-negative metres or m/s -> centi-units uint16 (HIL_GPS eph/epv/vel), saturated below 65535 (unknown)."""
    return _encode(m, 1e2, 0, UINT16_UNKNOWN - 1, "m")


def m_s2_to_mg(a: Any) -> Any:  # a scalar for a scalar, an array for an array
    """m/s^2 -> milli-g (int16), HIL_STATE_QUATERNION xacc/yacc/zacc."""
    return _encode(a, 1e3 / STANDARD_GRAVITY, -INT16_MAX, INT16_MAX, "a")


def mg_to_m_s2(mg: Any) -> Any:  # a scalar for a scalar, an array for an array
    return _decode(mg, 1e3 / STANDARD_GRAVITY)


def course_cdeg(v_NED: Any, min_speed_m_s: float = 0.0) -> Any:  # a scalar for a scalar, an array for an array
    """Course over ground [cdeg] (uint16, 0..35999, clockwise from north) of NED velocities (..., 3);
    65535 (unknown) where the horizontal speed is <= ``min_speed_m_s``."""
    v = _vec3(v_NED, "v_NED")
    deg = np.degrees(np.arctan2(v[..., 1], v[..., 0])) % 360.0
    cdeg = np.rint(deg * 100.0).astype(np.int64) % 36000
    cdeg = np.where(np.hypot(v[..., 0], v[..., 1]) > min_speed_m_s, cdeg, UINT16_UNKNOWN)
    return int(cdeg) if cdeg.ndim == 0 else cdeg
