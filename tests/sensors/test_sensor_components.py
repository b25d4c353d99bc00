"""Inertial and navigation sensors attached to the simulator: rates, topics, seeds, and readings that agree
with ground truth to within the configured noise."""

import math

import numpy as np
import pytest

from cufund.core.config import ConfigError
from cufund.core.messages import Topics
from cufund.scenarios import ScenarioConfig, load_scenario, run_scenario
from cufund.sensors import GPS_PRESETS, imu_preset, lla_to_enu


@pytest.fixture(scope="module")
def flight():
    return run_scenario(load_scenario("square_sensors"))


def test_each_sensor_publishes_on_its_topic_at_its_rate(flight):
    t_end = flight.result.sim_time_s
    for topic, rate in ((Topics.IMU, 200.0), (Topics.MAGNETOMETER, 100.0), (Topics.BAROMETER, 50.0)):
        t = flight.result.topics[topic]["t"]
        assert len(t) == pytest.approx(t_end * rate, abs=1.5)
        np.testing.assert_allclose(np.diff(t), 1.0 / rate, atol=1e-9)
    fixes = flight.result.topics[Topics.GPS]
    assert len(fixes["t"]) == pytest.approx(t_end * 10.0, abs=2.5)  # one per 0.1 s after the 0.1 s latency
    assert np.all(fixes["fix_type"] == 3)


def _truth_at(flight, t):
    s = flight.result.states
    idx = np.searchsorted(s["t"], t - 1e-9)
    assert np.allclose(s["t"][idx], t)
    return idx


def test_imu_agrees_with_ground_truth_within_its_noise(flight):
    params = imu_preset("icm42688p")
    imu = flight.result.topics[Topics.IMU]
    s = flight.result.states
    idx = _truth_at(flight, imu["t"])
    ok = (idx > 0) & (idx < len(s["t"]) - 1)
    idx, a_meas, w_meas = idx[ok], imu["f_I"][ok], imu["w_I"][ok]
    dt = s["t"][1] - s["t"][0]
    a_W = (s["v_W"][idx + 1] - s["v_W"][idx - 1]) / (2 * dt)  # independent of the model's own derivative
    q = s["q_WB"][idx]
    w, x, y, z = q.T
    R = np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )
    f_B = np.einsum("kji,kj->ki", R, a_W + [0, 0, 9.80665])
    moving = np.linalg.norm(a_W, axis=1).max()
    assert moving > 0.5  # the flight accelerates, so this is not just a static check
    nd_a, _, _ = params.accel.per_axis(3)
    nd_g, _, _ = params.gyro.per_axis(3)
    airborne = s["p_W"][idx, 2] > 0.05  # on the ground the contact makes velocity kinks
    res_a = (a_meas - f_B)[airborne]
    res_g = w_meas - s["w_B"][idx]
    for axis in range(3):
        # What remains is the white noise (sigma_w sqrt(rate)) about a constant bias.
        assert np.std(res_a[:, axis]) == pytest.approx(nd_a[axis] * math.sqrt(params.rate_hz), rel=0.15)
        assert np.std(res_g[:, axis]) == pytest.approx(nd_g[axis] * math.sqrt(params.rate_hz), rel=0.15)


def test_barometer_gps_and_magnetometer_track_the_truth(flight):
    s = flight.result.states
    baro = flight.result.topics[Topics.BAROMETER]
    idx = _truth_at(flight, baro["t"])
    err = baro["altitude_m"] - s["p_W"][idx, 2]
    assert np.std(err - np.mean(err)) < 0.3  # 1.2 Pa of noise is ~0.1 m; the offset is the turn-on bias
    gps = flight.result.topics[Topics.GPS]
    home = GPS_PRESETS["ublox_m8n"]().home
    enu = lla_to_enu(np.stack([gps["latitude_deg"], gps["longitude_deg"], gps["altitude_m"]], -1), home)
    idx = _truth_at(flight, gps["t"])
    horizontal = np.linalg.norm(enu[:, :2] - s["p_W"][idx, :2], axis=1)
    assert np.median(horizontal) < 5.0  # 2.5 m CEP plus a little drift
    assert np.max(np.abs(gps["v_W"] - s["v_W"][idx])) < 0.3
    mag = flight.result.topics[Topics.MAGNETOMETER]["m_B"]
    np.testing.assert_allclose(np.linalg.norm(mag, axis=1), 45e-6, rtol=0.05)


def test_sensor_streams_follow_the_seed():
    base = load_scenario("square_sensors").replace(duration=3.0)
    a = run_scenario(base).result.topics
    b = run_scenario(base).result.topics
    c = run_scenario(base.replace(seed=1)).result.topics
    for topic in (Topics.IMU, Topics.MAGNETOMETER, Topics.BAROMETER):
        for field, value in a[topic].items():
            assert value.tobytes() == b[topic][field].tobytes(), (topic, field)
    assert not np.array_equal(a[Topics.IMU]["f_I"], c[Topics.IMU]["f_I"])


def test_sensor_configuration_errors_name_the_field():
    with pytest.raises(ConfigError, match="sensors.imu.kind must be one of .*icm42688p.*got 'mpu9999'"):
        ScenarioConfig.from_dict({"sensors": {"imu": "mpu9999"}})
    with pytest.raises(ConfigError, match="unknown key 'rate' in sensors.gps .kind ublox_m8n."):
        ScenarioConfig.from_dict({"sensors": {"gps": {"kind": "ublox_m8n", "rate": 5}}})
    with pytest.raises(ConfigError, match="sensors.lidar.kind must be one of"):
        ScenarioConfig.from_dict({"sensors": {"lidar": "os1"}})
    cfg = ScenarioConfig.from_dict(
        {"sensors": {"gps": {"kind": "ideal_gps", "rate_hz": 5.0, "horizontal_sigma_m": 1.0}}}
    )
    assert ScenarioConfig.from_dict(cfg.to_dict()) == cfg


def test_recorded_ragged_topics_stay_lists_and_sensor_components_reset():
    """A LiDAR topic (frames of different sizes) is recorded as lists, and a second run of the same
    simulator repeats the first exactly (the LiDAR's frame counter and noise stream restart)."""
    import cufund
    from cufund.sensors import Lidar, LidarComponent, Mid360Pattern, mid360_params
    from cufund.simulator import Simulator

    world = cufund.worlds.load("imav2025_tunnel")
    quad = cufund.Quadrotor(cufund.vehicle.presets.cu_astro())
    lidar = LidarComponent(Lidar(Mid360Pattern(), mid360_params(range_noise_std=0.02, dropout=0.1, seed=3)), world)
    sim = Simulator(quad, record_topics=(Topics.POINT_CLOUD,))
    sim.add(lidar)
    runs = []
    for _ in range(2):
        quad.reset()
        quad.hover((1.0, 0.5, 1.0))
        runs.append(sim.run(0.35).topics[Topics.POINT_CLOUD])
    first, second = runs
    assert isinstance(first["ranges"], list) and len(first["ranges"]) == 3
    assert len({len(r) for r in first["ranges"]}) > 1  # frames differ in size
    np.testing.assert_array_equal(first["frame"], [0, 1, 2])
    np.testing.assert_array_equal(second["frame"], [0, 1, 2])
    for a, b in zip(first["ranges"], second["ranges"], strict=True):
        assert a.tobytes() == b.tobytes()


def test_sensor_noise_reaches_the_controller_through_an_attached_estimator():
    """With an estimator attached, the controllers fly on its output: the pose source's noise then changes the
    flight, and another seed gives another flight."""
    cfg = load_scenario("square_mocap", {"duration": 8.0, "sensors.pose.position_sigma_m": 0.01})
    clean = run_scenario(load_scenario("square_mocap", {"duration": 8.0})).result.states["p_W"]
    flights = [run_scenario(cfg.replace(seed=seed)).result for seed in (0, 0, 1)]
    assert all(f.status.value in ("completed", "timeout") for f in flights)
    p0, p0_again, p1 = (f.states["p_W"] for f in flights)
    assert p0.tobytes() == p0_again.tobytes()  # same seed, same flight
    assert not np.array_equal(p0, p1)  # the seed reaches the flight
    n = min(len(p0), len(clean))
    assert np.max(np.linalg.norm(p0[:n] - clean[:n], axis=1)) > 0.003  # and the noise does
