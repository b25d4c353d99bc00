"""The plant's faults (motor failure, motor efficiency loss, propeller imbalance) change exactly what they should
from their start time, in the square and in the tunnel.

Each faulty run is compared with the clean run of the same seed: the recorded states are identical, bit for bit,
before the fault's start; after it the expected change, against closed forms: the failed rotor's first-order
spin-down, the hover speed a weaker rotor needs (thrust ~ efficiency omega^2), the centrifugal force m r omega^2
in the rotor plane, and the acceleration it gives the body as the IMU reads it.
"""

import math

import numpy as np
import pytest

from cufund.core.components import Component
from cufund.core.config import ConfigError
from cufund.core.messages import Topics
from cufund.geometry import quat_to_matrix
from cufund.scenarios import ScenarioConfig, load_scenario
from cufund.scenarios.build import build_simulation, run_scenario
from cufund.sensors.faults import MotorEfficiency, MotorFailure, PropImbalance

T0 = 5.0  # the faults' start [s]: the square is on its first leg at 1.5 m


class _PlantProbe(Component):
    """Test harness: the plant's held inputs at every physics node (after the faults acted at that node)."""

    name = "plant_probe"
    rate_hz = 1000.0

    def __init__(self, plant):
        self.plant = plant

    def setup(self, bus):
        self.rows = []

    def step(self, t, bus):
        p = self.plant
        self.rows.append(
            (
                t,
                np.array(p.rotor_efficiency),
                p.force_ext_W.copy(),
                p.torque_ext_B.copy(),
                p.state.rotor_speeds.copy(),
                p.state.q.copy(),
            )
        )


def _run(faults, duration, scenario="square", overrides=(), probe=False, extra=()):
    config = load_scenario(scenario, list(overrides)).replace(faults=faults)
    built = build_simulation(config, tuple(extra))
    p = None
    if probe:
        p = _PlantProbe(built.simulator.vehicle)
        built.simulator.add(p)  # added last: it runs after the faults at each node
    result = built.simulator.run(duration)
    return result, p, built


@pytest.fixture(scope="module")
def clean():
    return _run(None, 9.0)[0]


def _identical_before(clean, faulty, t0):
    a, b = clean.states, faulty.states
    k = int(np.searchsorted(a["t"], t0))  # rows strictly before t0
    assert k > 1000
    for key in ("t", "p_W", "v_W", "q_WB", "w_B", "rotor_speeds"):
        assert a[key][:k].tobytes() == b[key][:k].tobytes(), key
    return k


def test_a_failed_motor_spins_down_and_the_vehicle_falls_and_rolls(clean):
    result, probe, built = _run({"motor_failure": {"t_start": T0, "motor": 0}}, 9.0, probe=True)
    k = _identical_before(clean, result, T0)
    s = result.states
    t, w0 = s["t"], s["rotor_speeds"][:, 0]
    tau = built.simulator.vehicle.params.tau_m
    after = (t >= T0) & (t <= T0 + 0.3)
    np.testing.assert_allclose(w0[after], w0[k] * np.exp(-(t[after] - T0) / tau), rtol=1e-12, atol=1e-9)
    assert w0[k] > 1000 and w0[np.searchsorted(t, T0 + 0.3)] < 1e-3 * w0[k]
    eta = np.array([r[1] for r in probe.rows if r[0] >= T0])
    assert np.all(eta == [0.0, 1.0, 1.0, 1.0])
    assert all(np.all(r[1] == 1.0) for r in probe.rows if r[0] < T0)
    # the vehicle loses its altitude and its attitude (no failsafe here): lower by > 0.5 m and tilted > 30 deg
    z = s["p_W"][:, 2]
    tilt = np.degrees(np.arccos(np.clip(quat_to_matrix(s["q_WB"])[:, 2, 2], -1, 1)))
    late = t >= T0 + 0.5
    assert z[late].min() < 1.0 and tilt[(t >= T0) & (t < T0 + 0.7)].max() > 30.0
    assert tilt[t < T0].max() < 10.0


def test_a_weaker_motor_ramps_down_and_the_controller_spins_it_faster(clean):
    eff, ramp = 0.6, 1.0
    result, probe, _ = _run(
        {"motor_efficiency": {"t_start": T0, "motor": 2, "efficiency": eff, "ramp_s": ramp}}, 9.0, probe=True
    )
    _identical_before(clean, result, T0)
    for t, eta, *_ in probe.rows:
        want = 1.0 if t < T0 else 1.0 + (eff - 1.0) * min((t - T0) / ramp, 1.0)
        assert eta[2] == pytest.approx(want, abs=1e-12) and np.all(eta[[0, 1, 3]] == 1.0), t
    # once settled, rotor 2 makes the same thrust as before: efficiency omega^2 equal, so omega x 1/sqrt(eff)
    s = result.states
    late = (s["t"] >= 7.5) & (s["t"] <= 9.0)
    w = s["rotor_speeds"][late].mean(axis=0)
    others = w[[0, 1, 3]].mean()
    assert w[2] / others == pytest.approx(1.0 / math.sqrt(eff), rel=0.03)
    assert result.status.value == "completed"


def test_a_propeller_imbalance_is_a_rotating_centrifugal_force_the_imu_feels(clean):
    mr = 1e-6
    faults = {"prop_imbalance": {"t_start": T0, "motor": 1, "imbalance_kg_m": mr}}
    result, probe, built = _run(faults, 7.0, probe=True)
    _identical_before(clean, result, T0)
    plant = built.simulator.vehicle
    r_hub, spin = plant.params.rotor_positions()[1], plant.params.rotor_spins()[1]
    before = [r for r in probe.rows if r[0] < T0]
    assert all(not r[2].any() and not r[3].any() for r in before)
    rows = [r for r in probe.rows if r[0] >= T0]
    angles = []
    for _t, _, F_W, M_B, omega, q in rows:
        F_B = quat_to_matrix(q).T @ F_W
        assert abs(F_B[2]) < 1e-9 * np.linalg.norm(F_B)  # in the rotor plane
        assert np.linalg.norm(F_B) == pytest.approx(mr * omega[1] ** 2, rel=1e-9)  # m r omega^2
        np.testing.assert_allclose(M_B, np.cross(r_hub, F_B), atol=1e-12)  # applied at the hub
        angles.append(math.atan2(F_B[1], F_B[0]))
    # it turns with the rotor: angle steps of the rotor speed times the node spacing (the trapezoid), in its sense
    step = np.angle(np.exp(1j * np.diff(angles)))
    omega = np.array([r[4][1] for r in rows])
    dt = np.diff([r[0] for r in rows])
    want = np.angle(np.exp(1j * spin * 0.5 * (omega[1:] + omega[:-1]) * dt))
    np.testing.assert_allclose(step, want, atol=1e-6)


def test_the_imbalance_reaches_the_imu_through_the_body_motion():
    """square_sensors' IMU (noise on, same seed in both runs): the faulty minus the clean accelerometer is the
    rotating force over the mass, RMS |F| / (m sqrt 2) per horizontal axis."""
    mr = 1e-6

    class Imu(Component):
        name = "imu_probe"
        rate_hz = 1000.0
        inputs = (Topics.IMU,)

        def setup(self, bus):
            self.sub, self.got = bus.subscribe(Topics.IMU), []

        def step(self, t, bus):
            self.got += self.sub.take()

    clean_imu, faulty_imu = Imu(), Imu()
    _run(None, 6.0, "square_sensors", extra=(clean_imu,))
    _, probe, built = _run(
        {"prop_imbalance": {"t_start": T0, "motor": 1, "imbalance_kg_m": mr}},
        6.0,
        "square_sensors",
        probe=True,
        extra=(faulty_imu,),
    )
    a = np.array([m.f_I for m in clean_imu.got])
    b = np.array([m.f_I for m in faulty_imu.got])
    t = np.array([m.t for m in clean_imu.got])
    assert a[t < T0].tobytes() == b[t < T0].tobytes()
    d = (b - a)[(t > T0 + 0.1)]
    mass = built.simulator.vehicle.params.mass
    omega = np.mean([r[4][1] for r in probe.rows if r[0] > T0 + 0.1])
    expect = mr * omega**2 / mass / math.sqrt(2)
    assert expect > 1.0  # m/s^2: far above the noise
    np.testing.assert_allclose(np.sqrt(np.mean(d[:, :2] ** 2, axis=0)), expect, rtol=0.05)


def test_a_plant_fault_acts_in_the_tunnel():
    """The tunnel (its LIO on, realistic profile) with a weaker motor from 4 s: identical before, then the
    plant's efficiency and a different flight."""
    clean = _run(None, 5.0, "tunnel")[0]
    faulty, probe, _ = _run(
        {"motor_efficiency": {"t_start": 4.0, "motor": 3, "efficiency": 0.7}}, 5.0, "tunnel", probe=True
    )
    k = _identical_before(clean, faulty, 4.0)
    assert faulty.states["rotor_speeds"][k:].tobytes() != clean.states["rotor_speeds"][k:].tobytes()
    assert all(r[1][3] == 0.7 for r in probe.rows if r[0] >= 4.0)


def test_plant_faults_parse_round_trip_and_list_in_the_metrics():
    cfg = load_scenario("square", ["faults.motor_failure.t_start=12", "faults.motor_failure.motor=2"])
    assert cfg.faults == (MotorFailure(12.0, 2),)
    assert ScenarioConfig.from_dict(cfg.to_dict()) == cfg
    two = cfg.replace(
        faults=[
            {"kind": "motor_efficiency", "t_start": 1, "motor": 0, "efficiency": 0.5, "ramp_s": 2},
            {"kind": "prop_imbalance", "t_start": 2, "motor": 3},
        ]
    )
    assert two.faults == (MotorEfficiency(1.0, 0, 0.5, 2.0), PropImbalance(2.0, 3, 1e-6))
    assert ScenarioConfig.from_dict(two.to_dict()) == two
    run = run_scenario(two.replace(duration=0.3))
    assert [f["kind"] for f in run.metrics["faults"]] == ["motor_efficiency", "prop_imbalance"]


@pytest.mark.parametrize(
    "faults, message",
    [
        ({"motor_failure": {"t_start": 1, "motor": 4}}, "faults.motor_failure.motor must be a rotor index 0-3"),
        ({"motor_failure": {"t_start": 1, "motor": 1.0}}, "faults.motor_failure.motor must be a rotor index"),
        ({"motor_failure": {"motor": 1}}, "missing key 't_start'"),
        (
            {"motor_efficiency": {"t_start": 1, "efficiency": 0}},
            "faults.motor_efficiency.efficiency must be a number in (0",
        ),
        ({"motor_efficiency": {"t_start": 1, "efficiency": 1.2}}, "faults.motor_efficiency.efficiency must be"),
        (
            {"motor_efficiency": {"t_start": 1, "ramp_s": -1}},
            "faults.motor_efficiency.ramp_s must be a number of seconds",
        ),
        ({"prop_imbalance": {"t_start": 1, "imbalance_kg_m": 0.01}}, "faults.prop_imbalance.imbalance_kg_m must be"),
        ({"prop_imbalance": {"t_start": 1, "imbalance": 1e-6}}, "unknown key 'imbalance' in faults.prop_imbalance"),
    ],
)
def test_bad_plant_faults_are_rejected_by_name(faults, message):
    with pytest.raises(ConfigError) as e:
        load_scenario("square").replace(faults=faults)
    assert message in str(e.value)


def test_each_fault_is_logged_when_it_begins_to_act(caplog):
    faults = {
        "motor_efficiency": {"t_start": 0.2, "motor": 1, "efficiency": 0.9},
        "gps_jump": {"t_start": 0.25, "offset_m": [1, 0, 0]},
    }
    with caplog.at_level("INFO", logger="cufund.faults"):
        run_scenario(load_scenario("square_sensors", ["duration=0.5"]).replace(faults=faults))
    lines = [r.getMessage() for r in caplog.records if r.name == "cufund.faults"]
    assert len(lines) == 2
    assert lines[0].startswith("fault motor_efficiency acts from t = 0.200000 s")
    # the first fix measured at or after 0.25 s (0.3 s, 10 Hz), published with the receiver's 0.1 s latency
    assert lines[1].startswith("fault gps_jump acts from t = 0.400000 s")
