"""LiDAR scan patterns: which directions a sensor fires in each frame, and when.

A pattern yields, for frame k, the firing time of every ray relative to the frame start [s], its
azimuth (from +x towards +y) and elevation (up from the x-y plane) [rad] in the sensor frame (FLU),
and its laser channel. Patterns are deterministic; non-repetitive ones (Livox) differ frame to frame
so that coverage of the field of view grows with integration time, as on the real sensors.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np


def _count(name: str, value: object, lo: int, hi: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {value!r}")
    return int(value)


def _firing_clock(
    point_rate: float, period: float, lasers: int, k: int
) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
    """Frame k of a solid-state LiDAR firing ``point_rate`` points/s round-robin over ``lasers``: the
    points per frame, their indices, absolute firing times [s] and laser channels."""
    n = int(round(point_rate * period))
    i = np.arange(n)
    return n, i, (k * n + i) / point_rate, (i % lasers).astype(np.int32)


@dataclasses.dataclass(frozen=True)
class ScanRays:
    """The rays of one frame, all (N,)."""

    t: np.ndarray
    """Firing time relative to the frame start, in [0, period) [s], non-decreasing."""
    azimuth: np.ndarray
    """[rad], from +x towards +y."""
    elevation: np.ndarray
    """[rad], up from the x-y plane."""
    channel: np.ndarray
    """Laser channel (ring) index, int32."""
    unit: np.ndarray | None = dataclasses.field(default=None, repr=False, compare=False)
    """(N, 3) the unit directions when the pattern computed them with the angles (else None)."""

    def directions(self) -> np.ndarray:
        """(N, 3) unit direction vectors in the sensor frame (``unit`` when given: do not modify it)."""
        if self.unit is not None:
            return self.unit
        ce = np.cos(self.elevation)
        return np.stack([ce * np.cos(self.azimuth), ce * np.sin(self.azimuth), np.sin(self.elevation)], 1)


@runtime_checkable
class ScanPattern(Protocol):
    """What a LiDAR needs from a scan pattern."""

    @property
    def period(self) -> float:
        """Frame period [s] (1 / frame rate)."""

    def frame(self, k: int) -> ScanRays:
        """The rays of frame ``k`` (k = 0, 1, 2, ...)."""


def _check(name: str, value: float, lo: float = 0.0, hi: float = np.inf, unit: str = "") -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a real number in ({lo}, {hi}] {unit}, got {value!r}".rstrip())
    value = float(value)
    if not (np.isfinite(value) and lo < value <= hi):
        raise ValueError(f"{name} must be in ({lo}, {hi}] {unit}, got {value}".rstrip())
    return value


@dataclasses.dataclass(frozen=True)
class PlanarPattern:
    """2-D scanner sweeping a fan in the x-y plane (Hokuyo UTM-30LX by default)."""

    fov: float = np.deg2rad(270.0)
    """Angular field of view, centred on +x [rad]."""
    resolution: float = np.deg2rad(0.25)
    """Angle between beams [rad]."""
    rate: float = 40.0
    """Scans per second [Hz]; the mirror turns once per scan."""

    repetitive: bool = dataclasses.field(default=True, init=False, repr=False)
    """Every frame is the same (a LiDAR may cache it)."""

    def __post_init__(self) -> None:
        _check("fov", self.fov, 0.0, 2 * np.pi, "[rad]")
        _check("resolution", self.resolution, 0.0, self.fov, "[rad]")
        _check("rate", self.rate, 0.0, 1e4, "[Hz]")

    @property
    def period(self) -> float:
        return 1.0 / self.rate

    def frame(self, k: int) -> ScanRays:
        n = int(round(self.fov / self.resolution)) + (0 if self.fov >= 2 * np.pi - 1e-9 else 1)
        az = -self.fov / 2 + self.resolution * np.arange(n)
        t = (az - az[0]) / (2 * np.pi) * self.period
        return ScanRays(t, az, np.zeros(n), np.zeros(n, np.int32))


@dataclasses.dataclass(frozen=True)
class SpinningPattern:
    """Mechanical 3-D LiDAR: a column of lasers at fixed elevations spinning about z."""

    elevations: tuple[float, ...]
    """Channel elevations [rad], channel i at elevations[i]."""
    columns: int
    """Firings per revolution (horizontal resolution = 2π / columns)."""
    rate: float = 10.0
    """Revolutions per second [Hz]; one frame per revolution."""

    repetitive: bool = dataclasses.field(default=True, init=False, repr=False)
    """Every frame is the same (a LiDAR may cache it)."""

    def __post_init__(self) -> None:
        try:
            el = np.asarray(self.elevations, dtype=float)
        except (TypeError, ValueError, OverflowError):
            el = np.full(1, np.nan)  # reported below
        if el.ndim != 1 or len(el) == 0 or not np.all(np.abs(el) < np.pi / 2):
            raise ValueError("elevations must be a non-empty list of angles in (-π/2, π/2) [rad]")
        if isinstance(self.columns, bool) or not isinstance(self.columns, (int, np.integer)) or self.columns < 1:
            raise ValueError(f"columns must be >= 1, got {self.columns}")
        _count("columns", self.columns, 1, 10**6)
        _check("rate", self.rate, 0.0, 1e3, "[Hz]")
        object.__setattr__(self, "elevations", tuple(float(e) for e in el))

    @property
    def period(self) -> float:
        return 1.0 / self.rate

    def frame(self, k: int) -> ScanRays:
        nc, ne = int(self.columns), len(self.elevations)
        col = np.repeat(np.arange(nc), ne)
        ch = np.tile(np.arange(ne, dtype=np.int32), nc)
        az = 2 * np.pi * col / nc
        return ScanRays(col * self.period / nc, az, np.asarray(self.elevations)[ch], ch)


def vlp16() -> SpinningPattern:
    """Velodyne VLP-16: 16 channels from -15° to +15° every 2°, 0.2° at 10 Hz (1800 columns)."""
    return SpinningPattern(tuple(np.deg2rad(np.arange(-15.0, 16.0, 2.0))), 1800, 10.0)


def os1_64() -> SpinningPattern:
    """Ouster OS1-64: 64 channels uniformly over ±16.6°, 1024 columns at 10 Hz."""
    return SpinningPattern(tuple(np.deg2rad(np.linspace(-16.6, 16.6, 64))), 1024, 10.0)


@dataclasses.dataclass(frozen=True)
class Mid360Pattern:
    """Livox Mid-360-like non-repetitive pattern: 360° × [-7°, +52°], ``point_rate`` points/s.

    Model (not Livox's proprietary firmware table, which ``CsvPattern`` can load): ``lasers``
    beams spaced evenly in azimuth turn at ``spin_rate`` while their elevation sweeps the vertical
    field sinusoidally at an irrational multiple of the spin, so no frame repeats and coverage of
    the field of view keeps growing over successive frames.
    """

    point_rate: float = 200_000.0
    """Points per second [1/s]."""
    rate: float = 10.0
    """Frames per second [Hz]."""
    elevation_min: float = np.deg2rad(-7.0)
    """[rad]"""
    elevation_max: float = np.deg2rad(52.0)
    """[rad]"""
    lasers: int = 4
    spin_rate: float = 10.0
    """Azimuth revolutions per second [Hz]."""
    sweep_ratio: float = 17.0 + (5**0.5 - 1) / 2
    """Elevation sweeps per revolution; irrational so the pattern never closes."""

    def __post_init__(self) -> None:
        _check("point_rate", self.point_rate, 0.0, 1e8, "[1/s]")
        _check("rate", self.rate, 0.0, 1e3, "[Hz]")
        for name in ("elevation_min", "elevation_max"):
            _check(name, getattr(self, name), -np.inf, np.inf, "[rad]")
        if not -np.pi / 2 < self.elevation_min < self.elevation_max < np.pi / 2:
            raise ValueError("need -π/2 < elevation_min < elevation_max < π/2 [rad]")
        _count("lasers", self.lasers, 1, 1024)
        _check("spin_rate", self.spin_rate, 0.0, 1e4, "[Hz]")
        _check("sweep_ratio", self.sweep_ratio, 0.0, 1e4)

    @property
    def period(self) -> float:
        return 1.0 / self.rate

    def frame(self, k: int) -> ScanRays:
        """Ray i of frame k fires at (k n + i) / point_rate (n rays per frame), laser i % lasers; azimuth
        2π (spin_rate t + channel / lasers) mod 2π; elevation (min + max) / 2 + (max - min) / 2 ·
        sin(2π spin_rate sweep_ratio t + π channel / lasers). Computed in C++ with the directions."""
        from cufund import _core

        n = int(round(self.point_rate * self.period))
        t, az, el, ch, d = _core.lidar.mid360_frame(
            int(k),
            n,
            self.point_rate,
            self.lasers,
            self.spin_rate,
            self.sweep_ratio,
            self.elevation_min,
            self.elevation_max,
        )
        return ScanRays(t, az, el, ch, d)


@dataclasses.dataclass(frozen=True)
class RosettePattern:
    """Livox Avia-like rosette from two Risley prisms: 70.4° × 77.2° forward, ``point_rate`` points/s.

    Each of ``lasers`` beams follows d(t) = (a/2)(e^{iω1 t} + e^{-iω2 t}) in the small-angle plane
    (two prisms counter-rotating at an irrational speed ratio), so the rosette precesses and never
    repeats; beams are offset vertically like the Avia's six lasers.
    """

    point_rate: float = 240_000.0
    """Points per second [1/s]."""
    rate: float = 10.0
    """Frames per second [Hz]."""
    fov_horizontal: float = np.deg2rad(70.4)
    """[rad]"""
    fov_vertical: float = np.deg2rad(77.2)
    """[rad]"""
    lasers: int = 6
    prism_rate: float = 97.0
    """Rotation rate of the first prism [Hz]."""
    prism_ratio: float = (1.0 + 5**0.5) / 2 - 0.01
    """Second prism rate / first; irrational so the rosette never closes."""

    def __post_init__(self) -> None:
        _check("point_rate", self.point_rate, 0.0, 1e8, "[1/s]")
        _check("rate", self.rate, 0.0, 1e3, "[Hz]")
        _check("fov_horizontal", self.fov_horizontal, 0.0, np.pi, "[rad]")
        _check("fov_vertical", self.fov_vertical, 0.0, np.pi, "[rad]")
        _count("lasers", self.lasers, 1, 1024)
        _check("prism_rate", self.prism_rate, 0.0, 1e5, "[Hz]")
        _check("prism_ratio", self.prism_ratio, 0.0, 1e3)

    @property
    def period(self) -> float:
        return 1.0 / self.rate

    def frame(self, k: int) -> ScanRays:
        n, i, t_abs, ch = _firing_clock(self.point_rate, self.period, self.lasers, k)
        w1 = 2 * np.pi * self.prism_rate
        w2 = w1 * self.prism_ratio
        offset = (ch - (self.lasers - 1) / 2) * 0.02  # beams 0.02 apart in the unit rosette
        x = 0.5 * (np.cos(w1 * t_abs) + np.cos(w2 * t_abs))
        y = 0.5 * (np.sin(w1 * t_abs) - np.sin(w2 * t_abs)) + offset
        scale = 1.0 / (1.0 + 0.02 * (self.lasers - 1) / 2)
        az = x * scale * self.fov_horizontal / 2
        el = y * scale * self.fov_vertical / 2
        return ScanRays(i / self.point_rate, az, el, ch)


def mid360() -> Mid360Pattern:
    return Mid360Pattern()


def avia() -> RosettePattern:
    return RosettePattern()


@dataclasses.dataclass(frozen=True)
class CsvPattern:
    """A pattern from a CSV of (time [s], azimuth [deg], zenith [deg]) rows, e.g. a Livox table.

    Zenith is measured from +z (elevation = 90° - zenith). Frames of ``1/rate`` seconds take
    consecutive slices of the table, wrapping around at its end, so a table longer than one frame
    is non-repetitive over its length. An optional header line is skipped.
    """

    path: str
    rate: float = 10.0
    """Frames per second [Hz]."""
    table: np.ndarray = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        _check("rate", self.rate, 0.0, 1e3, "[Hz]")
        p = Path(self.path)
        if not p.is_file():
            raise ValueError(f"pattern file {self.path!r} does not exist")
        try:
            data = np.genfromtxt(p, delimiter=",", dtype=float)
        except ValueError as e:
            raise ValueError(f"{self.path}: expected CSV rows of time, azimuth, zenith: {e}") from e
        data = np.atleast_2d(data)
        data = data[~np.all(np.isnan(data), axis=1)]  # a header line parses as NaNs
        if data.ndim != 2 or data.shape[1] != 3 or len(data) == 0 or not np.all(np.isfinite(data)):
            raise ValueError(
                f"{self.path}: expected finite CSV rows of (time, azimuth, zenith), got shape {data.shape}"
            )
        if np.any(np.diff(data[:, 0]) < 0):
            raise ValueError(f"{self.path}: time column must be non-decreasing")
        object.__setattr__(self, "table", data)

    @property
    def period(self) -> float:
        return 1.0 / self.rate

    def frame(self, k: int) -> ScanRays:
        tab = self.table
        t0 = tab[0, 0]
        span = tab[-1, 0] - t0
        step = np.median(np.diff(tab[:, 0])) if len(tab) > 1 else self.period
        span += step  # the table repeats after its last row
        start = (k * self.period) % span
        rel = tab[:, 0] - t0
        # rows falling into [start, start + period), wrapping around the table
        eps = 1e-9  # [s]: k * period need not be exact in floating point
        shifted = np.maximum(np.mod(rel - start + eps, span) - eps, 0.0)
        sel = np.nonzero(shifted < self.period - eps)[0]
        order = np.argsort(shifted[sel], kind="stable")
        sel = sel[order]
        az = np.deg2rad(tab[sel, 1])
        el = np.deg2rad(90.0 - tab[sel, 2])
        return ScanRays(shifted[sel], az, el, np.zeros(len(sel), np.int32))
