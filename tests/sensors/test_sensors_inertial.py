"""IMU and magnetometer against physics and against their configured noise (Allan deviation)."""

import dataclasses
import math

import numpy as np
import pytest

import cufund
from cufund.sensors import (
    EarthField,
    ImuModel,
    ImuParams,
    MagnetometerModel,
    MagnetometerParams,
    NoiseSpec,
    allan_deviation,
    fit_allan,
    imu_preset,
)

G = 9.80665


def rot_quat(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    return np.r_[math.cos(angle / 2), math.sin(angle / 2) * axis]


@pytest.mark.parametrize("name", ["icm42688p", "bmi088"])
def test_allan_deviation_recovers_configured_noise_within_10_percent(name):
    """N read at tau = 1 s and K from the +1/2 slope, per axis, from a long static record."""
    params = dataclasses.replace(imu_preset(name), rate_hz=100.0)  # 100 Hz keeps the record small
    params = dataclasses.replace(params, accel=dataclasses.replace(params.accel, turn_on_bias=0.0))
    model = ImuModel(params, seed=11)
    dt, duration = 0.01, 12_000.0  # ~1400 crossover times of the slowest axis (gyro, tau_c = sqrt(3) N / K)
    acc, gyr = model.measure_static(int(duration / dt))
    for rec, spec in ((acc, params.accel), (gyr, params.gyro)):
        nd, rw, _ = spec.per_axis(3)
        tau, adev = allan_deviation(rec, dt)
        i1 = int(np.argmin(np.abs(tau - 1.0)))
        assert tau[i1] == pytest.approx(1.0)
        for axis in range(3):
            fit = fit_allan(tau, adev[:, axis], record_s=duration)
            # At tau = 1 s the random walk adds (K^2 / 3) / (N^2 / 1) < 4 % to the variance for these parts.
            assert adev[i1, axis] == pytest.approx(nd[axis], rel=0.10)
            assert fit.white_noise_density == pytest.approx(nd[axis], rel=0.10)
            assert fit.bias_random_walk == pytest.approx(rw[axis], rel=0.10)


def test_static_level_imu_reads_plus_g_on_body_z():
    acc, gyr = ImuModel(ImuParams()).measure_static(5)
    np.testing.assert_array_equal(acc, np.tile([0.0, 0.0, G], (5, 1)))
    np.testing.assert_array_equal(gyr, np.zeros((5, 3)))


def test_imu_on_a_landed_and_a_hovering_quadrotor_reads_plus_g():
    params = cufund.vehicle.presets.cu_astro()
    quad = cufund.Quadrotor(params)
    imu = ImuModel(ImuParams(), gravity=params.gravity)
    quad.step(0.1, np.zeros(4))  # resting on the ground
    a, _ = imu.measure(quad.state.q, quad.state.w, quad.accel_W, quad.alpha_B)
    np.testing.assert_allclose(a, [0, 0, params.gravity], atol=1e-12)
    quad.hover((0.0, 0.0, 1.0))
    quad.step(0.1, np.full(4, params.hover_rotor_speed))
    a, _ = imu.measure(quad.state.q, quad.state.w, quad.accel_W, quad.alpha_B)
    np.testing.assert_allclose(a, [0, 0, params.gravity], atol=1e-9)


def test_tilted_imu_sees_gravity_on_the_axis_that_points_up():
    q = rot_quat([1, 0, 0], math.pi / 2)  # body y now points up
    a, _ = ImuModel(ImuParams()).measure(q, np.zeros(3), np.zeros(3), np.zeros(3))
    np.testing.assert_allclose(a, [0, G, 0], atol=1e-12)


def test_rotation_rate_and_lever_arm_centripetal_term():
    w = 3.0
    imu = ImuModel(ImuParams(p_BI=(0.1, 0.0, 0.0)))
    a, g = imu.measure(rot_quat([0, 0, 1], 0.4), np.array([0.0, 0.0, w]), np.zeros(3), np.zeros(3))
    np.testing.assert_allclose(g, [0, 0, w], atol=1e-15)
    np.testing.assert_allclose(a, [-w * w * 0.1, 0, G], atol=1e-12)  # w x (w x r) points to the axis
    # Tangential term alpha x r.
    a, _ = imu.measure(np.array([1.0, 0, 0, 0]), np.zeros(3), np.zeros(3), np.array([0.0, 0.0, 2.0]))
    np.testing.assert_allclose(a, [0, 0.2, G], atol=1e-12)


def test_mounting_rotation_scale_factor_and_saturation():
    upside_down = ImuParams(q_BI=tuple(rot_quat([1, 0, 0], math.pi)))
    a, _ = ImuModel(upside_down).measure_static(1)
    np.testing.assert_allclose(a[0], [0, 0, -G], atol=1e-12)
    scaled = ImuParams(accel_scale_factor=(0.0, 0.0, 0.01), gyro_range=1.0, saturation=True)
    a, g = ImuModel(scaled).measure(np.array([1.0, 0, 0, 0]), np.array([0.5, -3.0, 0.0]), np.zeros(3), np.zeros(3))
    assert a[2] == pytest.approx(1.01 * G, rel=1e-14)
    np.testing.assert_array_equal(g, [0.5, -1.0, 0.0])


def test_same_seed_same_stream_other_seed_different_and_chunking_invariant():
    params = imu_preset("bmi088")
    one = ImuModel(params, seed=5).measure_static(1000)
    two = ImuModel(params, seed=5).measure_static(1000)
    other = ImuModel(params, seed=6).measure_static(1000)
    assert one[0].tobytes() == two[0].tobytes() and one[1].tobytes() == two[1].tobytes()
    assert not np.array_equal(one[0], other[0])
    m = ImuModel(params, seed=5)
    z = np.zeros(3)
    pieces = [m.measure(np.array([1.0, 0, 0, 0]), z, z, z) for _ in range(1000)]
    assert np.array([p[0] for p in pieces]).tobytes() == one[0].tobytes()
    m.reset()
    assert m.measure_static(1000)[1].tobytes() == one[1].tobytes()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"rate_hz": 50.0}, "rate_hz must be between 100 and 1000"),
        ({"q_BI": (1.0, 1.0, 0.0, 0.0)}, "q_BI must be a unit quaternion"),
        ({"p_BI": (0.0, 0.0)}, "p_BI must be 3 finite numbers"),
        ({"gyro": NoiseSpec(-1.0)}, "white_noise_density must be a finite number >= 0"),
        ({"accel": {"white_noise_density": 1e-3, "colour": "pink"}}, "unknown key 'colour' in ImuParams.accel"),
    ],
)
def test_bad_imu_parameters_raise(change, message):
    with pytest.raises(ValueError, match=message):
        ImuParams(**change)


def test_imu_rejects_bad_truth():
    with pytest.raises(ValueError, match=r"w_B must have shape \(1, 3\)"):
        ImuModel(ImuParams()).measure(np.array([1.0, 0, 0, 0]), np.zeros(2), np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="a_W must be finite"):
        ImuModel(ImuParams()).measure(np.array([1.0, 0, 0, 0]), np.zeros(3), np.array([np.nan, 0, 0]), np.zeros(3))


def test_magnetometer_reads_the_earth_field_rotated_into_the_body():
    earth = EarthField(declination_deg=10.0, inclination_deg=60.0, intensity_T=50e-6)
    model = MagnetometerModel(MagnetometerParams(noise=NoiseSpec(), earth=earth))
    B_W = earth.B_W
    assert np.linalg.norm(B_W) == pytest.approx(50e-6)
    assert B_W[2] == pytest.approx(-50e-6 * math.sin(math.radians(60)))  # points down in the north
    # Yaw 0 in ENU: body x east, y north.
    np.testing.assert_allclose(model.measure(np.array([1.0, 0, 0, 0])), B_W, atol=1e-18)
    # A compass heading from the horizontal components recovers the yaw, given the declination.
    for yaw in (-2.0, 0.3, 1.5):
        m = model.measure(rot_quat([0, 0, 1], yaw))
        magnetic_north_yaw = math.atan2(m[0], m[1])  # angle from body y (north at yaw 0) to the field
        expected = math.radians(10.0) + yaw
        assert math.remainder(magnetic_north_yaw - expected, 2 * math.pi) == pytest.approx(0.0, abs=1e-12)


def test_magnetometer_hard_and_soft_iron():
    soft = ((1.1, 0.05, 0.0), (0.05, 0.9, 0.0), (0.0, 0.0, 1.0))
    p = MagnetometerParams(noise=NoiseSpec(), hard_iron_T=(1e-6, -2e-6, 3e-6), soft_iron=soft)
    m = MagnetometerModel(p).measure(np.array([1.0, 0, 0, 0]))
    np.testing.assert_allclose(m, np.array(soft) @ p.earth.B_W + [1e-6, -2e-6, 3e-6], atol=1e-18)
    with pytest.raises(ValueError, match="soft_iron must be an invertible 3x3 matrix"):
        MagnetometerParams(soft_iron=((1, 0, 0), (0, 1, 0), (0, 0, 0)))


def test_magnetometer_noise_is_seeded():
    a = MagnetometerModel(MagnetometerParams(), seed=1).measure(np.tile([1.0, 0, 0, 0], (100, 1)))
    b = MagnetometerModel(MagnetometerParams(), seed=1).measure(np.tile([1.0, 0, 0, 0], (100, 1)))
    c = MagnetometerModel(MagnetometerParams(), seed=2).measure(np.tile([1.0, 0, 0, 0], (100, 1)))
    assert a.tobytes() == b.tobytes() and not np.array_equal(a, c)
    assert np.std(a[:, 0]) == pytest.approx(0.3e-6, rel=0.2)  # the configured 0.3 uT RMS at 100 Hz
