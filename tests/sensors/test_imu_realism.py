"""The IMU's realism terms (issue 31): scale factor, cross-axis and g-sensitivity against the matrix formula,
rotor vibration against an FFT of the record (the line lands at its aliased frequency with the anti-alias
filter's gain, scipy's Butterworth as the reference), saturation of the total, batch == tick, seeding."""

import dataclasses
import math

import numpy as np
import pytest
import scipy.signal
from scipy.spatial.transform import Rotation

import cufund
from cufund.core.config import ConfigError
from cufund.core.messages import Odometry, Topics
from cufund.sensors import ImuModel, ImuParams, ImuSensor, NoiseSpec
from cufund.sensors.imu_vibration import VibrationSpec

G = 9.80665
RATE = 200.0
TWO_PI = 2.0 * math.pi


def explicit_matrix(scale, cross):
    """I + diag(s) + C written out from the documented order (xy, xz, yx, yz, zx, zy): row = output axis."""
    sx, sy, sz = scale
    xy, xz, yx, yz, zx, zy = cross
    return np.array([[1 + sx, xy, xz], [yx, 1 + sy, yz], [zx, zy, 1 + sz]])


def random_motion(k, seed=0):
    """A rotating, accelerating record: attitudes, body rates, accelerations (no lever arm)."""
    rng = np.random.default_rng(seed)
    rot = Rotation.random(k, random_state=seed)
    q_WB = np.roll(rot.as_quat(), 1, axis=1)  # scipy [x, y, z, w] -> [w, x, y, z]
    return rot, q_WB, rng.normal(0, 2.0, (k, 3)), rng.normal(0, 3.0, (k, 3)), rng.normal(0, 5.0, (k, 3))


def butter_gain(f_hz, corner_hz, order):
    """|H| and arg H of scipy's analog Butterworth at ``f_hz``."""
    b, a = scipy.signal.butter(order, TWO_PI * corner_hz, analog=True)
    _, h = scipy.signal.freqs(b, a, worN=TWO_PI * np.atleast_1d(np.asarray(f_hz, float)))
    return h


def line_amplitudes(x, rate, freqs):
    """Amplitude of the sinusoid at each frequency of an integer number of cycles in the record ``x`` (N, 3)."""
    n = len(x)
    spec = np.fft.rfft(x, axis=0) * 2.0 / n
    f = np.fft.rfftfreq(n, 1.0 / rate)
    out = []
    for fr in freqs:
        i = int(round(fr * n / rate))
        assert f[i] == pytest.approx(fr)
        out.append(np.abs(spec[i]))
    return np.array(out), np.abs(spec), f


# -- sensitivity matrix: scale factor, cross-axis, g-sensitivity --------------------------------------------


SCALE_A, SCALE_G = (0.003, -0.002, 0.004), (0.001, 0.002, -0.003)
CROSS_A = (0.01, -0.02, 0.005, 0.015, -0.007, 0.012)
CROSS_G = (-0.004, 0.008, 0.011, -0.006, 0.009, 0.003)
G_SENS = tuple(np.linspace(-2e-3, 3e-3, 9))


def sensitivity_params(**extra):
    return ImuParams(
        accel_scale_factor=SCALE_A,
        gyro_scale_factor=SCALE_G,
        accel_cross_axis=CROSS_A,
        gyro_cross_axis=CROSS_G,
        gyro_g_sensitivity=G_SENS,
        q_BI=tuple(np.roll(Rotation.from_euler("xyz", [3, -5, 90], degrees=True).as_quat(), 1)),
        **extra,
    )


def test_cross_axis_order_is_output_row_input_column():
    """xy = 0.01: 1 % of the y-axis input leaks into x (and nothing else changes)."""
    cross = (0.01, 0.0, 0.0, 0.0, 0.0, 0.0)
    imu = ImuModel(ImuParams(accel_cross_axis=cross, gyro_cross_axis=cross))
    a, g = imu.measure(np.array([1.0, 0, 0, 0]), np.array([0.0, 2.0, 0.0]), np.array([0.0, 3.0, 0.0]), np.zeros(3))
    np.testing.assert_allclose(a, [0.03, 3.0, G], rtol=1e-12)
    np.testing.assert_allclose(g, [0.02, 2.0, 0.0], rtol=1e-12)


def test_static_imu_reads_the_sensitivity_matrix_times_gravity():
    params = sensitivity_params()
    R_BI = Rotation.from_quat(np.roll(params.q_BI, -1)).as_matrix()
    f_I = R_BI.T @ [0.0, 0.0, G]
    acc, gyr = ImuModel(params).measure_static(3)
    np.testing.assert_allclose(acc, np.tile(explicit_matrix(SCALE_A, CROSS_A) @ f_I, (3, 1)), rtol=0, atol=1e-12)
    np.testing.assert_allclose(gyr, np.tile(np.reshape(G_SENS, (3, 3)) @ f_I, (3, 1)), rtol=0, atol=1e-12)


def test_rotating_record_matches_the_matrix_formula_in_batch_and_per_tick():
    params = sensitivity_params()
    rot, q, w, a, alpha = random_motion(400, seed=3)
    R_BI = Rotation.from_quat(np.roll(params.q_BI, -1)).as_matrix()
    f_B = rot.inv().apply(a + [0.0, 0.0, G])  # R_WB^T (a_W + g e_z)
    f_I = f_B @ R_BI  # R_BI^T f_B, row-wise
    w_I = w @ R_BI
    ref_a = f_I @ explicit_matrix(SCALE_A, CROSS_A).T
    ref_g = w_I @ explicit_matrix(SCALE_G, CROSS_G).T + f_I @ np.reshape(G_SENS, (3, 3)).T
    acc, gyr = ImuModel(params).measure(q, w, a, alpha)
    np.testing.assert_allclose(acc, ref_a, rtol=0, atol=1e-11)
    np.testing.assert_allclose(gyr, ref_g, rtol=0, atol=1e-11)
    tick = ImuModel(params)
    for i in range(0, 400, 37):
        ai, gi = tick.measure(q[i], w[i], a[i], alpha[i])
        np.testing.assert_allclose(ai, ref_a[i], rtol=0, atol=1e-11)
        np.testing.assert_allclose(gi, ref_g[i], rtol=0, atol=1e-11)


# -- vibration --------------------------------------------------------------------------------------------


def vib_params(**vib):
    spec = dict(
        accel_mps2=(1.0, 2.0, 3.0),
        gyro_radps=(0.1, 0.2, 0.3),
        hover_rotor_speed=TWO_PI * 170.0,
        anti_alias_hz=80.0,
        anti_alias_order=2,
    )
    spec.update(vib)
    return ImuParams(rate_hz=RATE, vibration=VibrationSpec(**spec))


def hover_record(params, rotor_speeds, k=2000, seed=0):
    """``k`` samples of a level IMU at rest with the rotors at ``rotor_speeds`` (4,) [rad/s]."""
    q = np.tile([1.0, 0.0, 0.0, 0.0], (k, 1))
    z = np.zeros((k, 3))
    return ImuModel(params, seed=seed).measure(q, z, z, z, np.tile(rotor_speeds, (k, 1)))


def test_one_rotor_at_170_hz_sampled_at_200_hz_shows_a_line_at_30_hz_with_the_filter_gain():
    params = vib_params()
    acc, gyr = hover_record(params, [TWO_PI * 170.0, 0.0, 0.0, 0.0])
    gain = abs(butter_gain(170.0, 80.0, 2)[0])  # scipy's Butterworth: about 0.22
    for rec, amp in ((acc - [0, 0, G], params.vibration.accel_mps2), (gyr, params.vibration.gyro_radps)):
        (line,), spectrum, f = line_amplitudes(rec, RATE, [30.0])
        np.testing.assert_allclose(line, np.asarray(amp) / 4 * gain, rtol=0.02)
        assert np.all(f[np.argmax(spectrum[1:], axis=0) + 1] == 30.0)  # the strongest line, on every axis


def test_four_rotors_give_four_aliased_lines_scaled_by_speed_squared():
    """Rotors at 150-180 Hz alias to 50, 40, 30, 20 Hz; each line is A/4 (w/w_hover)^2 |H(f)|."""
    params = vib_params(hover_rotor_speed=TWO_PI * 160.0, anti_alias_order=3)
    f_rot = np.array([150.0, 160.0, 170.0, 180.0])
    acc, gyr = hover_record(params, TWO_PI * f_rot)
    gain = np.abs(butter_gain(f_rot, 80.0, 3))
    expected = (f_rot / 160.0) ** 2 / 4 * gain
    for rec, amp in ((acc - [0, 0, G], params.vibration.accel_mps2), (gyr, params.vibration.gyro_radps)):
        lines, _, _ = line_amplitudes(rec, RATE, [50.0, 40.0, 30.0, 20.0])
        np.testing.assert_allclose(lines, expected[:, None] * np.asarray(amp)[None, :], rtol=0.02)


def test_harmonics_fold_back_with_their_ratio():
    """One rotor at 70 Hz with harmonics (1, 0.5): lines at 70 Hz and at 140 Hz -> 60 Hz (below Nyquist)."""
    params = vib_params(harmonics=(1.0, 0.5), hover_rotor_speed=TWO_PI * 70.0, anti_alias_order=4)
    acc, _ = hover_record(params, [TWO_PI * 70.0, 0.0, 0.0, 0.0])
    gain = np.abs(butter_gain([70.0, 140.0], 80.0, 4)) * [1.0, 0.5]
    lines, _, _ = line_amplitudes(acc - [0, 0, G], RATE, [70.0, 60.0])
    np.testing.assert_allclose(lines, gain[:, None] / 4 * np.asarray(params.vibration.accel_mps2), rtol=0.02)


def test_a_speed_ramp_is_a_chirp_with_the_integrated_phase():
    """Linear speed ramp: the rotor angle is w0 t + beta t^2 / 2 (the trapezoid is exact for it); the record is
    (A/4)(w/w_h)^2 |H(f)| sin(theta + arg H(f) + phi), f = w / 2 pi, with one constant phase phi per axis."""
    params = vib_params(hover_rotor_speed=TWO_PI * 40.0)
    k = 600
    t = np.arange(k) / RATE
    w0, beta = TWO_PI * 20.0, TWO_PI * 10.0  # 20 Hz rising 10 Hz/s to 50 Hz: stays below Nyquist
    w = w0 + beta * t
    q = np.tile([1.0, 0, 0, 0], (k, 1))
    z = np.zeros((k, 3))
    acc, _ = ImuModel(params).measure(q, z, z, z, np.c_[w, np.zeros((k, 3))])
    h = butter_gain(w / TWO_PI, 80.0, 2)
    theta = w0 * t + 0.5 * beta * t**2 + np.angle(h)
    amp = (w / params.vibration.hover_rotor_speed) ** 2 / 4 * np.abs(h)
    basis = np.c_[np.sin(theta), np.cos(theta)]  # sin(theta + phi) = cos(phi) sin(theta) + sin(phi) cos(theta)
    for axis in range(3):
        y = (acc[:, axis] - (G if axis == 2 else 0.0)) / (amp * params.vibration.accel_mps2[axis])
        coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
        assert np.hypot(*coef) == pytest.approx(1.0, abs=1e-9)
        np.testing.assert_allclose(basis @ coef, y, atol=1e-9)


def test_no_vibration_with_rotors_stopped_or_unknown():
    base = dataclasses.replace(vib_params(), accel=NoiseSpec(1e-3, 1e-4, 0.01), gyro=NoiseSpec(1e-4, 1e-5, 0.001))
    quiet = dataclasses.replace(base, vibration=VibrationSpec())
    k = 50
    q = np.tile([1.0, 0, 0, 0], (k, 1))
    z = np.zeros((k, 3))
    ref = ImuModel(quiet, seed=4).measure(q, z, z, z)
    for rotors in (np.zeros((k, 4)), None):
        got = ImuModel(base, seed=4).measure(q, z, z, z, rotors)
        np.testing.assert_array_equal(got[0], ref[0])
        np.testing.assert_array_equal(got[1], ref[1])


def test_saturation_clips_the_total_with_vibration():
    """A 20 m/s^2 z line on top of +g exceeds a 12 m/s^2 range: the record is the unclipped one, clipped."""
    wide = vib_params(accel_mps2=(0.0, 0.0, 80.0), anti_alias_hz=1e5)
    narrow = dataclasses.replace(wide, accel_range=12.0, saturation=True)
    rotors = [TWO_PI * 170.0, 0.0, 0.0, 0.0]
    free, _ = hover_record(wide, rotors, k=400)
    clipped, _ = hover_record(narrow, rotors, k=400)
    assert free[:, 2].max() > 25.0  # ~ 9.8 + 20
    np.testing.assert_array_equal(clipped, np.clip(free, -12.0, 12.0))
    assert np.sum(clipped[:, 2] == 12.0) > 50


def full_params():
    return dataclasses.replace(
        sensitivity_params(p_BI=(0.02, -0.01, 0.03)),
        rate_hz=RATE,
        accel=NoiseSpec(1e-3, 1e-4, 0.02),
        gyro=NoiseSpec(1e-4, 1e-5, 0.002),
        vibration=VibrationSpec(
            accel_mps2=(2.0, 2.5, 4.0),
            gyro_radps=(0.05, 0.04, 0.03),
            harmonics=(1.0, 0.4, 0.2),
            speed_spread=0.02,
            hover_rotor_speed=900.0,
            anti_alias_hz=80.0,
            anti_alias_order=2,
        ),
    )


def test_batch_and_tick_paths_agree_and_a_seed_repeats_its_record():
    params = full_params()
    _, q, w, a, alpha = random_motion(300, seed=8)
    rng = np.random.default_rng(1)
    rotors = np.clip(900.0 + np.cumsum(rng.normal(0, 20.0, (300, 4)), axis=0), 0.0, None)
    rotors[:20] = 0.0  # spin-up from rest
    batch = ImuModel(params, seed=2)
    acc, gyr = batch.measure(q[:100], w[:100], a[:100], alpha[:100], rotors[:100])  # in two chunks
    acc2, gyr2 = batch.measure(q[100:], w[100:], a[100:], alpha[100:], rotors[100:])
    acc, gyr = np.vstack([acc, acc2]), np.vstack([gyr, gyr2])
    tick = ImuModel(params, seed=2)
    one = [tick.measure(q[i], w[i], a[i], alpha[i], rotors[i]) for i in range(300)]
    np.testing.assert_allclose(np.array([o[0] for o in one]), acc, rtol=0, atol=1e-10)
    np.testing.assert_allclose(np.array([o[1] for o in one]), gyr, rtol=0, atol=1e-12)
    whole = ImuModel(params, seed=2).measure(q, w, a, alpha, rotors)  # chunking changes only the rounding
    np.testing.assert_allclose(whole[0], acc, rtol=0, atol=1e-12)
    again = ImuModel(params, seed=2).measure(q, w, a, alpha, rotors)
    np.testing.assert_array_equal(again[0], whole[0])  # same seed, same record
    tick.reset()  # reset restarts the noise and the rotors' angles
    np.testing.assert_array_equal(tick.measure(q, w, a, alpha, rotors)[0], whole[0])
    other = ImuModel(dataclasses.replace(params, accel=NoiseSpec(), gyro=NoiseSpec()), seed=3)
    same_noise_free = ImuModel(dataclasses.replace(params, accel=NoiseSpec(), gyro=NoiseSpec()), seed=2)
    assert not np.allclose(other.measure(q, w, a, alpha, rotors)[0], same_noise_free.measure(q, w, a, alpha, rotors)[0])


def test_vibration_leaves_the_noise_stream_unchanged():
    """Terms off -> the record of before; the vibration has its own stream (the noise draws are the same)."""
    params = full_params()
    off = dataclasses.replace(params, vibration=VibrationSpec())
    k = 64
    q = np.tile([1.0, 0, 0, 0], (k, 1))
    z = np.zeros((k, 3))
    with_vib = ImuModel(params, seed=9).measure(q, z, z, z, np.full((k, 4), 900.0))
    without = ImuModel(off, seed=9).measure(q, z, z, z, np.full((k, 4), 900.0))
    vib = dataclasses.replace(params, accel=NoiseSpec(), gyro=NoiseSpec())
    only_vib = ImuModel(vib, seed=9).measure(q, z, z, z, np.full((k, 4), 900.0))
    only_clean = ImuModel(dataclasses.replace(vib, vibration=VibrationSpec()), seed=9).measure(q, z, z, z)
    np.testing.assert_allclose(with_vib[0] - without[0], only_vib[0] - only_clean[0], atol=1e-12)


# -- the sensor in the simulator reads the true rotor speeds ---------------------------------------------


def test_imu_sensor_vibrates_at_the_simulated_rotor_speed():
    """A hovering vehicle (no controller: rotor speeds held at hover): ground truth carries the rotor speeds,
    and the IMU's record minus a vibration-free twin is a line at the aliased hover rotor frequency."""
    vp = cufund.vehicle.presets.cu_astro()
    records = []
    spec = VibrationSpec(accel_mps2=(3.0, 3.0, 3.0), hover_rotor_speed=vp.hover_rotor_speed, anti_alias_hz=1e5)
    for vibration in (spec, VibrationSpec()):
        quad = cufund.Quadrotor(vp)
        sim = cufund.Simulator(quad, physics_rate_hz=1000, record_topics=(Topics.IMU, Topics.TRUTH_ODOMETRY))
        sim.add(ImuSensor(ImuParams(rate_hz=RATE, vibration=vibration), seed=1, gravity=vp.gravity))
        quad.hover((0.0, 0.0, 2.0))
        rec = sim.run(2.0)
        records.append(rec.topics[Topics.IMU]["f_I"])
    truth = rec.topics[Topics.TRUTH_ODOMETRY]["rotor_speeds"]
    np.testing.assert_allclose(truth, np.full_like(truth, vp.hover_rotor_speed), rtol=1e-6)
    diff = records[0] - records[1]
    n = len(diff)
    spectrum = np.abs(np.fft.rfft(diff, axis=0))
    f = np.fft.rfftfreq(n, 1.0 / RATE)
    f_rotor = vp.hover_rotor_speed / TWO_PI
    alias = abs(f_rotor - RATE * round(f_rotor / RATE))
    peak = f[np.argmax(spectrum[1:], axis=0) + 1]
    np.testing.assert_allclose(peak, alias, atol=2.0 * RATE / n)


def test_imu_sensor_without_rotor_speeds_in_truth_does_not_vibrate():
    params = vib_params()
    t = Odometry(0.0, np.zeros(3), np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3), np.zeros(3), np.zeros(3))
    msg = ImuSensor(params).measure(0.0, t)
    np.testing.assert_allclose(msg.f_I, [0.0, 0.0, G], atol=1e-15)


# -- validation --------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "change, message",
    [
        ({"accel_cross_axis": (0.0,) * 5}, "ImuParams.accel_cross_axis must be 6"),
        ({"gyro_cross_axis": (0.0, 0.0, 0.0, 0.0, 0.0, math.nan)}, "ImuParams.gyro_cross_axis must be 6"),
        ({"gyro_g_sensitivity": (0.0,) * 3}, "ImuParams.gyro_g_sensitivity must be 9"),
        ({"vibration": {"anti_alias_hz": 0.0}}, "ImuParams.vibration.anti_alias_hz must be a finite number > 0"),
        ({"vibration": {"anti_alias_order": 0}}, "ImuParams.vibration.anti_alias_order must be an integer from 1"),
        ({"vibration": {"anti_alias_order": 9}}, "ImuParams.vibration.anti_alias_order"),
        ({"vibration": {"anti_alias_order": 2.5}}, "ImuParams.vibration.anti_alias_order"),
        ({"vibration": {"accel_mps2": (1.0, 0.0)}}, "ImuParams.vibration.accel_mps2 must be 3"),
        ({"vibration": {"gyro_radps": (-1.0, 0.0, 0.0)}}, "ImuParams.vibration.gyro_radps must be 3"),
        ({"vibration": {"harmonics": ()}}, "ImuParams.vibration.harmonics must be a list"),
        ({"vibration": {"speed_spread": -0.1}}, "ImuParams.vibration.speed_spread must be a finite number >= 0"),
        ({"vibration": {"accel_mps2": (1.0, 0.0, 0.0)}}, "ImuParams.vibration.hover_rotor_speed must be > 0"),
        ({"vibration": {"wobble": 1.0}}, "wobble"),
    ],
)
def test_bad_realism_parameters_name_the_field(change, message):
    with pytest.raises(ConfigError, match=message.replace("(", r"\(")):
        ImuParams.from_dict(change)


def test_bad_rotor_speeds_raise():
    model = ImuModel(vib_params())
    q, z = np.array([1.0, 0, 0, 0]), np.zeros(3)
    with pytest.raises(ValueError, match="rotor_speeds must be finite"):
        model.measure(q, z, z, z, np.array([1.0, math.nan, 0.0, 0.0]))
    with pytest.raises(ValueError, match="rotor_speeds must have shape"):
        model.measure(np.tile(q, (3, 1)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((2, 4)))
