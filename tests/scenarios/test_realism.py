"""The scenario's ``realism`` profile (issue 31): parsing and overriding, the seeded draws, and what the simulated
parts get against what flight software is given."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from cufund.apps.cli import main
from cufund.core.config import ConfigError
from cufund.geometry import quat_conjugate, quat_mul, quat_to_matrix
from cufund.scenarios import load_scenario
from cufund.scenarios.build import build_simulation, run_scenario
from cufund.scenarios.realism import RealismConfig
from cufund.scenarios.schema import ScenarioConfig, parse_overrides

G0 = 9.80665


def _component(built, type_name):
    found = [c for c in built.simulator.components if type(c).__name__ == type_name]
    assert len(found) == 1, [type(c).__name__ for c in built.simulator.components]
    return found[0]


def _tilt_deg(q):
    """Angle between the body z axis and the world's [deg]."""
    return math.degrees(math.acos(min(1.0, quat_to_matrix(np.asarray(q))[2, 2])))


# ---------------------------------------------------------------------------------------------------------------
# parsing


def test_profiles_and_overrides_parse():
    assert RealismConfig.parse(None) == RealismConfig.parse("ideal") == RealismConfig()
    real = RealismConfig.parse("realistic")
    assert real.vehicle.pad_tilt_max_deg == 3.0 and real.lidar.max_range_at_10pct == 40.0
    mixed = RealismConfig.parse({"profile": "realistic", "imu": {"scale_factor_ppm": 3000}})
    assert mixed.imu.scale_factor_ppm == 3000.0
    assert mixed.imu.cross_axis_pct == real.imu.cross_axis_pct  # the rest is the profile's
    assert mixed.lidar == real.lidar
    vib = RealismConfig.parse({"profile": "realistic", "imu": {"vibration": {"anti_alias_hz": 500}}})
    assert vib.imu.vibration.anti_alias_hz == 500.0 and vib.imu.vibration.accel_mps2 == real.imu.vibration.accel_mps2
    # a mapping without a profile starts from ideal
    assert RealismConfig.parse({"calibration": {"lidar_time_offset_s": 0.001}}).profile == "ideal"
    for value in ("ideal", "realistic", mixed, vib):
        r = RealismConfig.parse(value)
        assert RealismConfig.parse(r.to_data()) == r  # round trip through plain data
        assert RealismConfig.parse(json.loads(json.dumps(r.to_data()))) == r
    assert RealismConfig.parse("realistic").to_data() == "realistic"


@pytest.mark.parametrize(
    ("value", "named"),
    [
        ("superreal", "realism.profile"),
        ({"profile": "realistic", "imus": {}}, "'imus'"),
        ({"imu": {"scale_ppm": 1}}, "'scale_ppm' in realism.imu"),
        ({"imu": {"vibration": {"amplitude": 1}}}, "'amplitude' in realism.imu.vibration"),
        ({"lidar": {"range_noise_per_m": -0.1}}, "realism.lidar.range_noise_per_m"),
        ({"vehicle": {"mass_pct": "five"}}, "realism.vehicle.mass_pct"),
        ({"calibration": {"extrinsic_rotation_deg": float("nan")}}, "realism.calibration.extrinsic_rotation_deg"),
        ({"imu": {"vibration": {"accel_mps2": [1, 2]}}}, "realism.imu.vibration.accel_mps2"),
        ({"imu": {"vibration": {"anti_alias_order": 2.5}}}, "realism.imu.vibration.anti_alias_order"),
        ({"vehicle": {"pad_tilt_max_deg": 45}}, "realism.vehicle.pad_tilt_max_deg"),
        (3, "realism must be a profile name"),
        ({"imu": 3}, "realism.imu must be a mapping"),
    ],
)
def test_bad_realism_names_the_field(value, named):
    with pytest.raises(ConfigError, match=named.replace(".", r"\.").replace("(", r"\(")):
        ScenarioConfig.from_dict({"realism": value})


def test_set_forms_through_the_cli_parser():
    """``--set realism=realistic`` and dotted keys below it, in either order of appearance after the profile, and
    dotted keys on a scenario without the key."""
    both = load_scenario("square", ["realism=realistic", "realism.imu.scale_factor_ppm=3000"])
    assert both.realism.profile == "realistic" and both.realism.imu.scale_factor_ppm == 3000.0
    nested = load_scenario(
        "square", parse_overrides(["realism.vehicle.mass_pct=2", "realism.imu.vibration.gyro_dps=[1, 1, 1]"])
    )
    assert nested.realism.profile == "ideal" and nested.realism.vehicle.mass_pct == 2.0
    assert nested.realism.imu.vibration.gyro_dps == (1.0, 1.0, 1.0)
    # a scenario that says realistic, overridden field by field (the string becomes {profile: ...})
    again = both.with_overrides(["realism.lidar.incidence_noise=0"])
    assert again.realism.profile == "realistic" and again.realism.lidar.incidence_noise == 0.0
    assert again.realism.imu.scale_factor_ppm == 3000.0
    flow = load_scenario("square", ["realism={profile: realistic, vehicle: {pad_tilt_max_deg: 1}}"])
    assert flow.realism.vehicle.pad_tilt_max_deg == 1.0 and flow.realism.vehicle.mass_pct == 5.0
    with pytest.raises(ConfigError, match=r"'nosuch' in realism\.imu"):
        load_scenario("square", ["realism=realistic", "realism.imu.nosuch=1"])


def test_cli_run_records_the_profile_and_draws(tmp_path):
    out = tmp_path / "run"
    argv = ["run", "square", "--set", "realism=realistic", "--set", "realism.imu.scale_factor_ppm=3000"]
    assert main([*argv, "--out", str(out), "--no-replay"]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    r = metrics["realism"]
    assert r["profile"] == "realistic"
    assert r["config"] == {"profile": "realistic", "imu": {"scale_factor_ppm": 3000.0}}
    assert 0.0 <= r["pad_tilt_deg"] <= 3.0 and 0.95 <= r["mass_scale"] <= 1.05
    # the run folder's config.yaml repeats the run, profile and overrides included
    again = tmp_path / "again"
    assert main(["run", str(out / "config.yaml"), "--out", str(again), "--no-replay"]) == 0
    assert json.loads((again / "metrics.json").read_text())["realism"] == r
    assert main(["run", "square", "--set", "realism.imu.bogus=1", "--out", str(tmp_path / "bad")]) == 2


# ---------------------------------------------------------------------------------------------------------------
# draws


def _draws(config, seed):
    scenario = load_scenario("square_lio", [f"seed={seed}"]).replace(realism=config)
    from cufund.scenarios.build import ScenarioBuildContext

    return ScenarioBuildContext(scenario).realism


def test_draws_are_seeded_and_within_bounds():
    real = RealismConfig.parse("realistic")
    a, b, c = _draws(real, 1), _draws(real, 1), _draws(real, 2)
    assert a == b  # same seed, same draws (bit for bit)
    assert a.plant != c.plant and a.mounting_errors != c.mounting_errors and a.imu_errors != c.imu_errors
    n = 300
    draws = [_draws(real, s) for s in range(n)]
    plant = np.array(
        [
            [d.plant.mass_scale, *d.plant.inertia_scale, d.plant.thrust_constant_scale, d.plant.torque_constant_scale]
            for d in draws
        ]
    )
    bounds = np.array([0.05, 0.10, 0.10, 0.10, 0.05, 0.05])
    assert np.all(np.abs(plant - 1.0) <= bounds)
    # uniform within +-b: standard deviation b / sqrt(3), within 15 % for 300 draws
    np.testing.assert_allclose(np.std(plant - 1.0, axis=0), bounds / math.sqrt(3), rtol=0.15)
    lag = np.array([d.plant.motor_time_constant_scale for d in draws])
    assert np.all(np.abs(lag - 1.0) <= 0.20)
    tilt = np.array([d.plant.pad_tilt_deg for d in draws])
    assert np.all((tilt >= 0) & (tilt <= 3.0)) and abs(np.mean(tilt) - 1.5) < 0.2
    # the pad attitude tilts by the drawn angle, towards the drawn direction
    for d in draws[:20]:
        assert _tilt_deg(d.plant.q_W_pad) == pytest.approx(d.plant.pad_tilt_deg, abs=1e-9)
        z = quat_to_matrix(np.asarray(d.plant.q_W_pad))[:, 2]
        if d.plant.pad_tilt_deg > 0.1:
            az = math.degrees(math.atan2(z[1], z[0])) % 360
            assert az == pytest.approx(d.plant.pad_tilt_direction_deg, abs=1e-6)
    # calibration: N(0, sigma) per axis, so |dp| ~ 1.6 sigma = 8 mm, |dtheta| ~ 0.48 deg, |dt| ~ 1.6 ms
    dp = np.array([d.mounting_errors["lidar"].dp_B for d in draws])
    dth = np.degrees(np.array([d.mounting_errors["lidar"].dtheta_B for d in draws]))
    dt = np.array([d.mounting_errors["lidar"].time_offset_s for d in draws])
    np.testing.assert_allclose(np.std(dp, axis=0), 0.005, rtol=0.15)
    np.testing.assert_allclose(np.std(dth, axis=0), 0.3, rtol=0.15)
    assert np.std(dt) == pytest.approx(0.002, rel=0.15)
    assert np.median(np.linalg.norm(dp, axis=1)) == pytest.approx(0.005 * math.sqrt(2.366), rel=0.15)
    assert "imu" not in a.mounting_errors  # the body frame is the IMU's: its mounting stays exact
    sf = np.array([d.imu_errors["imu"].accel_scale_factor for d in draws])
    np.testing.assert_allclose(np.std(sf, axis=0), 2500e-6, rtol=0.15)
    g = np.array([d.imu_errors["imu"].gyro_g_sensitivity for d in draws])
    assert np.std(g) == pytest.approx(0.05 * math.pi / 180 / G0, rel=0.1)


def test_draws_of_one_section_do_not_move_another():
    """Each section (and sensor) draws from its own stream: switching the IMU terms off leaves the plant's and the
    calibration's draws as they were."""
    real = RealismConfig.parse("realistic")
    no_imu = RealismConfig.parse({"profile": "realistic", "imu": {"scale_factor_ppm": 0, "cross_axis_pct": 0}})
    a, b = _draws(real, 5), _draws(no_imu, 5)
    assert a.plant == b.plant and a.mounting_errors == b.mounting_errors


def test_ideal_draws_nothing():
    d = _draws(RealismConfig(), 7)
    assert d.imu_errors == {} and d.mounting_errors == {}
    nominal = load_scenario("square_lio").vehicle_params()
    assert d.simulated_vehicle(nominal) is nominal
    stated = load_scenario("square_lio").sensors["lidar"].extrinsic
    assert d.simulated_extrinsic("sensors.lidar", stated) is stated


# ---------------------------------------------------------------------------------------------------------------
# what the simulated parts get, and what flight software is given


def test_simulated_parts_differ_from_what_flight_software_reads():
    config = load_scenario("square_lio", ["realism=realistic"])
    built = build_simulation(config)
    ctx = built.context
    draws = ctx.realism
    # flight software's view: the scenario as stated
    assert ctx.vehicle == config.vehicle_params()
    stated_imu = config.sensors["imu"].params
    assert ctx.imu_params() == stated_imu
    _, lidar_spec = ctx.sensor_of_type("lidar")
    assert lidar_spec.extrinsic == config.sensors["lidar"].extrinsic
    # the simulated plant
    plant = built.simulator.vehicle.params
    assert plant.mass == pytest.approx(ctx.vehicle.mass * draws.plant.mass_scale)
    assert plant.k_f == pytest.approx(ctx.vehicle.k_f * draws.plant.thrust_constant_scale)
    assert plant.k_f * plant.c_m == pytest.approx(ctx.vehicle.k_f * ctx.vehicle.c_m * draws.plant.torque_constant_scale)
    assert plant.tau_m == pytest.approx(ctx.vehicle.tau_m * draws.plant.motor_time_constant_scale)
    np.testing.assert_allclose(
        np.diag(plant.inertia_matrix), np.diag(ctx.vehicle.inertia_matrix) * draws.plant.inertia_scale
    )
    # the simulated IMU: calibrated accelerometer bias, drawn scale factors, vibration at the plant's hover speed
    imu = _component(built, "ImuSensor").model.params
    assert imu.accel.turn_on_bias == pytest.approx(3e-3 * G0)
    assert stated_imu.accel.turn_on_bias == pytest.approx(20e-3 * G0)  # the part's raw zero-g offset
    assert imu.gyro == stated_imu.gyro
    np.testing.assert_allclose(imu.accel_scale_factor, draws.imu_errors["imu"].accel_scale_factor)
    assert imu.accel_scale_factor != stated_imu.accel_scale_factor
    np.testing.assert_allclose(imu.gyro_cross_axis, draws.imu_errors["imu"].gyro_cross_axis)
    assert imu.vibration.hover_rotor_speed == pytest.approx(plant.hover_rotor_speed)
    assert imu.vibration.gyro_radps == pytest.approx(tuple(v * math.pi / 180 for v in (0.3, 0.3, 0.2)))
    # the simulated LiDAR: mounted where the drawn error puts it, stamped with the drawn clock offset
    lidar = _component(built, "LidarComponent").lidar
    err = draws.mounting_errors["lidar"]
    T_stated = lidar_spec.extrinsic
    np.testing.assert_allclose(np.subtract(lidar.T_BL.t, T_stated.t), err.dp_B, atol=1e-15)
    dq = quat_mul(np.asarray(lidar.T_BL.q), quat_conjugate(np.asarray(T_stated.q)))
    angle = 2 * math.atan2(np.linalg.norm(dq[1:]), abs(dq[0]))
    assert angle == pytest.approx(np.linalg.norm(err.dtheta_B), rel=1e-9)
    assert lidar.params.time_offset_s == err.time_offset_s != 0.0
    assert lidar.params.max_range_at_10pct == 40.0 and lidar.params.mixed_pixel_probability == 0.1


def test_ideal_builds_the_scenario_as_stated_with_a_calibrated_accelerometer():
    """Under ``ideal`` every simulated part is exactly what the scenario states, but for the accelerometer's raw
    turn-on bias, which a perfect calibration removes (``accel_residual_bias_mg: null`` keeps it)."""
    config = load_scenario("square_lio", ["realism=ideal"])
    assert config.realism.profile == "ideal" and load_scenario("square_lio").realism.profile == "realistic"
    built = build_simulation(config)
    assert built.simulator.vehicle.params == config.vehicle_params()
    stated = config.sensors["imu"].params
    assert stated.accel.turn_on_bias > 0  # the ICM-42688-P's datasheet zero-g offset
    imu = _component(built, "ImuSensor").model.params
    assert imu.accel.turn_on_bias == 0.0
    assert imu == dataclasses.replace(stated, accel=dataclasses.replace(stated.accel, turn_on_bias=0.0))
    assert built.context.imu_params() == stated  # flight software reads the part as stated
    raw = build_simulation(load_scenario("square_lio", ["realism=ideal", "realism.imu.accel_residual_bias_mg=null"]))
    assert _component(raw, "ImuSensor").model.params == stated
    lidar = _component(built, "LidarComponent").lidar
    assert lidar.T_BL == config.sensors["lidar"].extrinsic
    defaults = type(lidar.params)()
    for f in dataclasses.fields(lidar.params):
        if f.name not in ("range_min", "range_max", "range_noise_std", "dropout", "seed", "nthreads"):
            assert getattr(lidar.params, f.name) == getattr(defaults, f.name), f.name
    assert tuple(built.simulator.vehicle.state.q) == (1.0, 0.0, 0.0, 0.0)


def test_square_ideal_metrics_equal_a_run_without_the_key():
    plain = run_scenario(load_scenario("square"))
    ideal = run_scenario(load_scenario("square", ["realism={profile: ideal}"]))
    np.testing.assert_array_equal(plain.result.states["p_W"], ideal.result.states["p_W"])
    np.testing.assert_array_equal(plain.result.states["q_WB"], ideal.result.states["q_WB"])
    skip = {"wall_time_s", "real_time_factor", "component_seconds"}
    assert {k: v for k, v in plain.metrics.items() if k not in skip} == {
        k: v for k, v in ideal.metrics.items() if k not in skip
    }
    assert plain.metrics["realism"]["profile"] == "ideal" and plain.metrics["realism"]["pad_tilt_deg"] == 0.0


def test_square_flies_under_realistic_from_a_tilted_pad():
    """The plant differs from the controller's model and the pad is tilted: the vehicle rests at the pad's tilt
    until it takes off, and the square still completes."""
    run = run_scenario(load_scenario("square", ["realism=realistic"]))
    m = run.metrics
    tilt = m["realism"]["pad_tilt_deg"]
    assert tilt > 0.5 and m["realism"]["mass_scale"] != 1.0
    assert m["status"] == "completed"
    assert m["tracking_rmse_m"] < 0.03
    states = run.result.states
    on_pad = states["p_W"][:, 2] <= 0.0
    first_flight = int(np.argmax(~on_pad))
    assert first_flight > 10  # some records on the pad before take-off
    tilts = [_tilt_deg(q) for q in states["q_WB"][:first_flight]]
    np.testing.assert_allclose(tilts, tilt, atol=1e-9)  # at rest on the pad, exactly its tilt
    np.testing.assert_allclose(states["v_W"][:first_flight], 0.0, atol=0.0)
    # horizontal creep on the slope while the rotors spin up (no static friction in the contact model): sub-mm
    assert np.linalg.norm(states["p_W"][first_flight, :2] - states["p_W"][0, :2]) < 1e-3


@pytest.mark.parametrize(
    ("q", "named"),
    [
        ((1.0, 0.0, 0.0), "ground_attitude must be 4"),
        ((2.0, 0.0, 0.0, 0.0), "ground_attitude"),
        ((math.cos(math.radians(22.5)), math.sin(math.radians(22.5)), 0.0, 0.0), "at most 30 deg"),
    ],
)
def test_ground_attitude_is_validated(q, named):
    from cufund.vehicle import presets

    with pytest.raises(ConfigError, match=named):
        dataclasses.replace(presets.cu_astro(), ground_attitude=q)


def test_calibration_error_moves_every_mounted_sensor_but_the_imu():
    """A camera (and a LiDAR mounted at the body origin, no T_BL given) is moved by its own drawn error; the IMU's
    mounting stays exact."""
    config = load_scenario(
        "square_lio",
        [
            "realism.calibration={extrinsic_translation_m: 0.005, extrinsic_rotation_deg: 0.3}",
            "sensors.depth={kind: d435_depth, T_BC: {p: [0.1, 0.0, 0.0], q: [1, 0, 0, 0]}}",
            "sensors.lidar={kind: mid360}",
        ],
    )
    built = build_simulation(config)
    errors = built.context.realism.mounting_errors
    assert set(errors) == {"depth", "lidar"}
    cam = _component(built, "CameraComponent").camera
    np.testing.assert_allclose(np.subtract(cam.T_BC.t, (0.1, 0.0, 0.0)), errors["depth"].dp_B, atol=1e-15)
    lidar = _component(built, "LidarComponent").lidar
    np.testing.assert_allclose(lidar.T_BL.t, errors["lidar"].dp_B, atol=1e-15)
    assert errors["depth"] != errors["lidar"]
    imu = _component(built, "ImuSensor").model.params
    assert imu.p_BI == (0.0, 0.0, 0.0) and imu.q_BI == (1.0, 0.0, 0.0, 0.0)
    assert built.context.sensor_of_type("camera")[1].extrinsic.t == (0.1, 0.0, 0.0)  # flight software: as stated


def test_vibration_alone_reaches_the_simulated_imu():
    """A profile with only the vibration on still gives the simulated IMU its vibration (no drawn errors needed)."""
    built = build_simulation(
        load_scenario(
            "square_lio",
            ["realism=ideal", "realism.imu.vibration.accel_mps2=[1,1,2]", "duration=0.1"],
        )
    )
    imu = _component(built, "ImuSensor").model.params
    assert imu.vibration.accel_mps2 == (1.0, 1.0, 2.0) and imu.vibration.enabled
    assert imu.accel_scale_factor == (0.0, 0.0, 0.0) and imu.accel_cross_axis == (0.0,) * 6
