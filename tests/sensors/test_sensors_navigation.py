"""Barometer against the ISA table, GPS against WGS-84 geometry, and their noise, latency and outages."""

import math

import numpy as np
import pytest

from cufund.sensors import (
    BAROMETER_PRESETS,
    GPS_PRESETS,
    BarometerModel,
    BarometerParams,
    GeoPoint,
    GpsModel,
    GpsParams,
    enu_to_lla,
    isa_altitude,
    isa_pressure,
    lla_to_enu,
)
from cufund.sensors.geodesy import WGS84_A, WGS84_F, lla_to_ecef


@pytest.mark.parametrize(
    ("altitude", "pressure"),
    [(0.0, 101325.0), (1000.0, 89874.6), (2000.0, 79495.2), (5000.0, 54019.9), (11000.0, 22632.1)],
)
def test_isa_pressure_matches_the_standard_atmosphere_table(altitude, pressure):
    # ISO 2533 / ICAO standard atmosphere table values [Pa].
    assert isa_pressure(altitude) == pytest.approx(pressure, abs=0.6)
    assert isa_altitude(pressure) == pytest.approx(altitude, abs=0.06)


def test_barometer_altitude_matches_isa_without_noise():
    model = BarometerModel(BarometerParams(home_altitude_m=120.0))
    z = np.array([0.0, 1.5, 50.0, 300.0])
    pressure, altitude = model.measure(z)
    np.testing.assert_allclose(pressure, isa_pressure(120.0 + z), rtol=1e-15)
    np.testing.assert_allclose(altitude, z, atol=1e-6)
    assert model.temperature_k(0.0) == pytest.approx(288.15 - 0.0065 * 120.0)


def test_barometer_noise_and_seed():
    params = BAROMETER_PRESETS["ms5611"]()
    p1, a1 = BarometerModel(params, seed=3).measure(np.zeros(5000))
    p2, _ = BarometerModel(params, seed=3).measure(np.zeros(5000))
    p3, _ = BarometerModel(params, seed=4).measure(np.zeros(5000))
    assert p1.tobytes() == p2.tobytes() and not np.array_equal(p1, p3)
    white = np.diff(p1) / math.sqrt(2)  # differencing removes the offset and (mostly) the slow drift
    assert np.std(white) == pytest.approx(1.2, rel=0.1)  # the datasheet's 0.012 mbar RMS
    assert np.std(a1 - np.mean(a1)) > 0.05  # about 0.1 m of altitude noise per Pa


def test_wgs84_reference_points():
    np.testing.assert_allclose(lla_to_ecef(0.0, 0.0, 0.0), [WGS84_A, 0, 0], atol=1e-9)
    np.testing.assert_allclose(lla_to_ecef(math.pi / 2, 0.0, 0.0), [0, 0, WGS84_A * (1 - WGS84_F)], atol=1e-6)
    home = GeoPoint(22.4196, 114.2068, 30.0)
    np.testing.assert_allclose(enu_to_lla(np.zeros(3), home), [22.4196, 114.2068, 30.0], atol=1e-12)


def test_enu_to_lla_follows_the_meridian_and_parallel_radii():
    home = GeoPoint(47.3769, 8.5417, 400.0)
    lat = math.radians(home.latitude_deg)
    e2 = WGS84_F * (2 - WGS84_F)
    meridian = WGS84_A * (1 - e2) / (1 - e2 * math.sin(lat) ** 2) ** 1.5
    prime = WGS84_A / math.sqrt(1 - e2 * math.sin(lat) ** 2)
    north = enu_to_lla(np.array([0.0, 100.0, 0.0]), home)
    east = enu_to_lla(np.array([100.0, 0.0, 0.0]), home)
    assert math.radians(north[0] - home.latitude_deg) * (meridian + home.altitude_m) == pytest.approx(100.0, rel=1e-6)
    assert math.radians(east[1] - home.longitude_deg) * (prime + home.altitude_m) * math.cos(lat) == pytest.approx(
        100.0, rel=1e-6
    )
    assert north[2] - home.altitude_m == pytest.approx(100.0**2 / (2 * meridian), rel=1e-3)  # Earth curves away


def test_gps_round_trips_to_enu_within_a_millimetre(rng):
    home = GeoPoint(-33.8688, 151.2093, 58.0)
    p = rng.uniform(-10_000, 10_000, (1000, 3)) * [1, 1, 0.1]
    np.testing.assert_allclose(lla_to_enu(enu_to_lla(p, home), home), p, atol=1e-3, rtol=0)
    model = GpsModel(GpsParams(home=home, rate_hz=10.0))
    fix = model.measure(0.0, p[0], np.array([1.0, 2.0, 3.0]))
    back = lla_to_enu(np.array([fix.latitude_deg, fix.longitude_deg, fix.altitude_m]), home)
    np.testing.assert_allclose(back, p[0], atol=1e-3, rtol=0)
    np.testing.assert_array_equal(fix.v_W, [1.0, 2.0, 3.0])
    assert fix.fix_type == 3 and fix.satellites >= 6


def test_gps_noise_statistics_match_the_receiver_preset():
    params = GPS_PRESETS["ublox_m8n"]()
    params = GpsParams(**{**params.__dict__, "drift_m_per_sqrt_s": 0.0, "latency_s": 0.0})
    model = GpsModel(params, seed=9)
    fixes = [model.measure(k / params.rate_hz, np.zeros(3), np.zeros(3)) for k in range(4000)]
    enu = lla_to_enu(np.array([[f.latitude_deg, f.longitude_deg, f.altitude_m] for f in fixes]), params.home)
    horizontal = np.linalg.norm(enu[:, :2], axis=1)
    assert np.median(horizontal) == pytest.approx(2.5, rel=0.05)  # the data sheet's 2.5 m CEP
    assert np.std(enu[:, 2]) == pytest.approx(params.vertical_sigma_m, rel=0.05)
    assert np.std([f.v_W[0] for f in fixes]) == pytest.approx(0.05, rel=0.05)


def test_gps_latency_and_outage():
    params = GpsParams(rate_hz=10.0, latency_s=0.2, outages=((1.0, 1.5),))
    model = GpsModel(params)
    fixes = {}
    for k in range(30):
        t = k / 10.0
        fix = model.measure(t, np.array([t, 0.0, 0.0]), np.zeros(3))
        fixes[round(t, 3)] = fix
    assert fixes[0.0] is None and fixes[0.1] is None  # nothing before the latency has elapsed
    f = fixes[0.5]
    assert f.t == pytest.approx(0.3)  # measured 0.2 s before it arrives
    assert lla_to_enu(np.array([f.latitude_deg, f.longitude_deg, f.altitude_m]), params.home)[0] == pytest.approx(
        0.3, abs=1e-3
    )
    lost = fixes[1.4]  # measured at 1.2 s, inside the outage
    assert lost.fix_type == 0 and math.isnan(lost.latitude_deg) and lost.satellites < params.min_satellites
    assert fixes[1.9].fix_type == 3  # measured at 1.7 s, after it


def test_gps_seed_determinism():
    params = GPS_PRESETS["ublox_m9n"]()
    runs = []
    for seed in (1, 1, 2):
        m = GpsModel(params, seed=seed)
        runs.append([m.measure(k * 0.1, np.zeros(3), np.zeros(3)) for k in range(50)])
    lat = [[f.latitude_deg for f in r if f is not None] for r in runs]
    assert lat[0] == lat[1] and lat[0] != lat[2]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"rate_hz": 0.0}, "rate_hz must be in"),
        ({"horizontal_sigma_m": -1.0}, "horizontal_sigma_m must be a finite number >= 0"),
        ({"outages": ((2.0, 1.0),)}, "outages must have end > start"),
        ({"home": {"latitude_deg": 95.0, "longitude_deg": 0.0}}, "latitude_deg must be in"),
        ({"home": {"latitude_deg": 5.0, "lon": 0.0}}, "unknown key 'lon' in GpsParams.home"),
    ],
)
def test_bad_gps_parameters_raise(kwargs, message):
    with pytest.raises(ValueError, match=message):
        GpsParams(**kwargs)


def test_bad_barometer_parameters_raise():
    with pytest.raises(ValueError, match="sea_level_temperature_k must be in"):
        BarometerParams(sea_level_temperature_k=-5.0)
    with pytest.raises(ValueError, match="z_W must be finite"):
        BarometerModel(BarometerParams()).measure(np.array([np.nan]))
