"""Sensor faults as scenario options act on what the sensors publish, and on nothing else.

Each faulty run of ``square_lio`` (estimator off, so the flight does not depend on the sensors) is compared with
the clean run of the same seed: the sensor models' own streams are untouched, so every difference is the fault's.
"""

import numpy as np
import pytest

from cufund.core.components import Component
from cufund.core.config import ConfigError
from cufund.core.messages import Topics
from cufund.scenarios import ScenarioConfig, load_scenario
from cufund.scenarios.build import build_simulation
from cufund.sensors.faults import ImuBiasStep, LidarDegraded, LidarDropout, parse_faults

DURATION = 3.0
DROPOUT = (0.5, 0.8)  # start, duration [s]
STEP_T, STEP_ACC, STEP_GYR = 1.5, (0.2, -0.1, 0.05), (0.0, 0.02, 0.05)
DEGRADE_T, FRACTION, NOISE = 2.0, 0.5, 0.05


class _Recorder(Component):
    name = "fault_probe"
    rate_hz = 1000.0
    inputs = (Topics.IMU, Topics.POINT_CLOUD)

    def setup(self, bus):
        self._imu, self._lidar = bus.subscribe(Topics.IMU), bus.subscribe(Topics.POINT_CLOUD)
        self.imu, self.clouds = [], []

    def step(self, t, bus):
        self.imu += self._imu.take()
        self.clouds += [(t, m) for m in self._lidar.take()]  # (visible time, cloud)


def _run(faults):
    config = load_scenario("square_lio", ["estimator=null", "realism=ideal"]).replace(faults=faults)
    rec = _Recorder()
    build_simulation(config, (rec,)).simulator.run(DURATION)
    return rec


FAULTS = {
    "lidar_dropout": {"t_start": DROPOUT[0], "duration": DROPOUT[1]},
    "imu_bias_step": {"t_start": STEP_T, "accel": list(STEP_ACC), "gyro": list(STEP_GYR)},
    "lidar_degraded": {"t_start": DEGRADE_T, "fraction": FRACTION, "noise_m": NOISE},
}


@pytest.fixture(scope="module")
def runs():
    return _run(None), _run(FAULTS)


def test_lidar_topic_is_silent_during_a_dropout_and_unchanged_around_it(runs):
    clean, faulty = runs
    t_clean = np.array([t for t, _ in clean.clouds])
    t_faulty = np.array([t for t, _ in faulty.clouds])
    in_window = (t_clean >= DROPOUT[0]) & (t_clean < DROPOUT[0] + DROPOUT[1])
    assert np.count_nonzero(in_window) >= 7  # the clean LiDAR did publish in the window
    assert not np.any((t_faulty >= DROPOUT[0]) & (t_faulty < DROPOUT[0] + DROPOUT[1]))
    np.testing.assert_array_equal(t_faulty, t_clean[~in_window])
    for (_, a), (_, b) in zip(
        [c for c in clean.clouds if c[0] < DEGRADE_T and not DROPOUT[0] <= c[0] < sum(DROPOUT)],
        faulty.clouds,
        strict=False,  # the clean frames before the degradation against the faulty run's first frames
    ):
        if b.t + 0.1 > DEGRADE_T:
            break
        np.testing.assert_array_equal(a.points_L, b.points_L)


def test_imu_bias_step_shifts_the_measurements_by_the_step_from_its_time_on(runs):
    clean, faulty = runs
    t = np.array([m.t for m in clean.imu])
    assert np.array_equal(t, [m.t for m in faulty.imu])
    f_c, f_f = np.array([m.f_I for m in clean.imu]), np.array([m.f_I for m in faulty.imu])
    w_c, w_f = np.array([m.w_I for m in clean.imu]), np.array([m.w_I for m in faulty.imu])
    before, after = t < STEP_T, t >= STEP_T
    assert np.count_nonzero(before) > 100 and np.count_nonzero(after) > 100
    np.testing.assert_array_equal(f_f[before], f_c[before])
    np.testing.assert_array_equal(w_f[before], w_c[before])
    np.testing.assert_allclose((f_f - f_c)[after].mean(axis=0), STEP_ACC, atol=1e-12)
    np.testing.assert_allclose((w_f - w_c)[after].mean(axis=0), STEP_GYR, atol=1e-12)
    np.testing.assert_allclose(np.ptp((f_f - f_c)[after], axis=0), 0.0, atol=1e-12)


def test_degraded_lidar_keeps_the_fraction_and_adds_the_range_noise(runs):
    clean, faulty = runs
    by_stamp = {m.t: m for _, m in clean.clouds}
    degraded = [(t, m) for t, m in faulty.clouds if t >= DEGRADE_T]
    assert len(degraded) >= 8
    residuals = []
    for _, m in degraded:
        ref = by_stamp[m.t]
        assert len(m) == round(FRACTION * len(ref))
        idx = np.searchsorted(ref.dt, m.dt)  # the clean frame's dt are sorted and distinct
        np.testing.assert_array_equal(ref.dt[idx], m.dt)
        np.testing.assert_array_equal(ref.channel[idx], m.channel)
        assert len(np.unique(idx)) == len(idx)
        # each point moved along its own ray, to its noisy range
        u_ref = ref.points_L[idx] / np.linalg.norm(ref.points_L[idx], axis=1, keepdims=True)
        u = m.points_L / np.linalg.norm(m.points_L, axis=1, keepdims=True)
        assert np.max(np.linalg.norm(u - u_ref, axis=1)) < 1e-5
        np.testing.assert_allclose(np.linalg.norm(m.points_L, axis=1), m.ranges, rtol=1e-6, atol=1e-5)
        residuals.append(m.ranges - ref.ranges[idx])
    r = np.concatenate(residuals)
    assert abs(r.mean()) < 4 * NOISE / np.sqrt(len(r))
    assert abs(r.std() / NOISE - 1) < 0.02  # ~ 80 000 samples: the std is known to about 0.3 %
    # the kept points are spread over the frame, not a prefix
    assert np.ptp(degraded[0][1].dt) > 0.09


def test_faulty_runs_repeat_bit_for_bit(runs):
    _, faulty = runs
    again = _run(FAULTS)
    assert len(again.clouds) == len(faulty.clouds)
    for (ta, a), (tb, b) in zip(faulty.clouds, again.clouds, strict=True):
        assert ta == tb
        np.testing.assert_array_equal(a.points_L, b.points_L)
        np.testing.assert_array_equal(a.ranges, b.ranges)


def test_faults_parse_from_a_map_or_a_list_and_round_trip():
    cfg = load_scenario(
        "square_lio",
        [
            "faults.lidar_dropout.t_start=12",
            "faults.imu_bias_step.t_start=20",
            "faults.imu_bias_step.gyro=[0, 0, 0.05]",
        ],
    )
    assert cfg.faults == (LidarDropout(12.0), ImuBiasStep(20.0, gyro=(0.0, 0.0, 0.05)))
    assert ScenarioConfig.from_dict(cfg.to_dict()) == cfg
    two = cfg.replace(
        faults=[{"kind": "lidar_dropout", "t_start": 3}, {"kind": "lidar_dropout", "t_start": 9, "duration": 2.5}]
    )
    assert two.faults == (LidarDropout(3.0), LidarDropout(9.0, 2.5))
    assert ScenarioConfig.from_dict(two.to_dict()) == two
    assert parse_faults({"lidar_degraded": {"t_start": 1}}) == (LidarDegraded(1.0, 0.5, 0.05),)
    assert load_scenario("square_lio").faults == ()


@pytest.mark.parametrize(
    "faults, message",
    [
        ({"lidar_dropout": {"t_start": 1, "durations": 2}}, "unknown key 'durations' in faults.lidar_dropout"),
        ({"lidar_dropout": {"duration": 2}}, "missing key 't_start'"),
        ({"lidar_blackout": {"t_start": 1}}, "unknown fault kind 'lidar_blackout'"),
        ([{"t_start": 1}], "faults[0] must be a mapping with a 'kind' key"),
        ({"lidar_degraded": {"t_start": 1, "fraction": 0}}, "fraction must be a share of points in (0, 1]"),
        ({"lidar_degraded": {"t_start": 1, "noise_m": -0.1}}, "noise_m must be a range noise"),
        ({"imu_bias_step": {"t_start": 1, "gyro": [0, 0]}}, "faults.imu_bias_step.gyro"),
        ({"lidar_dropout": {"t_start": float("nan")}}, "t_start must be a number of seconds"),
        ({"lidar_dropout": {"t_start": 1, "duration": 0}}, "duration must be a number of seconds in (0"),
        ("lidar_dropout", "faults must be a map"),
    ],
)
def test_bad_faults_are_rejected_by_name(faults, message):
    with pytest.raises(ConfigError) as e:
        load_scenario("square_lio").replace(faults=faults)
    assert message in str(e.value)


def test_a_fault_needs_its_sensor():
    cfg = load_scenario("square_lio", ["estimator=null"])
    with pytest.raises(ConfigError, match="no imu sensor named 'imu2'"):
        build_simulation(cfg.replace(faults={"imu_bias_step": {"t_start": 1, "sensor": "imu2"}}))
    no_lidar = cfg.replace(sensors={"imu": cfg.sensors["imu"]})
    with pytest.raises(ConfigError, match="lidar_dropout needs a lidar sensor"):
        build_simulation(no_lidar.replace(faults={"lidar_dropout": {"t_start": 1}}))
