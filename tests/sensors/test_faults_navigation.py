"""GPS, magnetometer and barometer faults change exactly what they should, from their start time on.

Each faulty run of ``square_sensors`` (no estimator: the flight does not depend on the sensors, so the truth is the
same with and without faults) is compared with the clean run of the same seed, message by message: identical before
the fault's start, the fault's exact change after it. The references are independent of the faults' code: the
geodesy's own ENU conversion for the GPS, the ISA formula written out here for the barometer.
"""

import math

import numpy as np
import pytest

from cufund.core.components import Component
from cufund.core.config import ConfigError
from cufund.core.messages import Topics
from cufund.scenarios import ScenarioConfig, load_scenario
from cufund.scenarios.build import build_simulation
from cufund.sensors.faults import BaroStep, GpsDrift, GpsJump, MagDisturbance, parse_faults
from cufund.sensors.geodesy import lla_to_enu

DURATION = 6.0
T0 = 2.0  # every fault's start [s]
JUMP = (3.0, -4.0, 1.5)
DRIFT = (0.5, 0.25, -0.1)
FIELD = (20e-6, -5e-6, 40e-6)
BARO_M = 2.5


class _Recorder(Component):
    name = "fault_probe"
    rate_hz = 1000.0
    inputs = (Topics.GPS, Topics.MAGNETOMETER, Topics.BAROMETER)

    def setup(self, bus):
        self._subs = {t: bus.subscribe(t) for t in self.inputs}
        self.got = {t: [] for t in self.inputs}

    def step(self, t, bus):
        for topic, sub in self._subs.items():
            self.got[topic] += sub.take()


def _run(faults):
    config = load_scenario("square_sensors").replace(faults=faults)
    rec = _Recorder()
    built = build_simulation(config, (rec,))
    built.simulator.run(DURATION)
    return rec.got, config


@pytest.fixture(scope="module")
def clean():
    return _run(None)


def _enu(fixes, home):
    return lla_to_enu(np.array([[f.latitude_deg, f.longitude_deg, f.altitude_m] for f in fixes]), home)


def _split(a, b, t0):
    """The paired messages of two runs before and from ``t0`` (by measurement stamp); the stamps must agree."""
    assert [m.t for m in a] == [m.t for m in b]
    before = [(x, y) for x, y in zip(a, b, strict=True) if x.t < t0]
    after = [(x, y) for x, y in zip(a, b, strict=True) if x.t >= t0]
    assert before and after
    return before, after


def _same(pairs):
    """Bit-identical messages (NaN equal to NaN)."""
    for x, y in pairs:
        for k in x.__dataclass_fields__:
            a, b = np.asarray(getattr(x, k)), np.asarray(getattr(y, k))
            assert a.tobytes() == b.tobytes(), (k, x, y)


def test_gps_jump_offsets_every_fix_by_exactly_the_offset_from_its_start(clean):
    got, config = _run({"gps_jump": {"t_start": T0, "offset_m": list(JUMP)}})
    home = config.sensors["gps"].params.home
    before, after = _split(clean[0][Topics.GPS], got[Topics.GPS], T0)
    _same(before)
    d = _enu([y for _, y in after], home) - _enu([x for x, _ in after], home)
    np.testing.assert_allclose(d, np.tile(JUMP, (len(after), 1)), atol=1e-6)
    for x, y in after:
        np.testing.assert_array_equal(x.v_W, y.v_W)


def test_gps_drift_grows_at_its_rate_and_moves_the_velocity_with_it(clean):
    got, config = _run({"gps_drift": {"t_start": T0, "rate_mps": list(DRIFT)}})
    home = config.sensors["gps"].params.home
    before, after = _split(clean[0][Topics.GPS], got[Topics.GPS], T0)
    _same(before)
    d = _enu([y for _, y in after], home) - _enu([x for x, _ in after], home)
    elapsed = np.array([x.t - T0 for x, _ in after])
    np.testing.assert_allclose(d, elapsed[:, None] * np.array(DRIFT), atol=1e-6)
    assert elapsed[-1] > 3.0  # grown to > 1.5 m on x by the end
    for x, y in after:
        np.testing.assert_allclose(y.v_W - x.v_W, DRIFT, atol=1e-12)


def test_gps_dropout_reports_no_fix_for_its_duration_only(clean):
    got, _ = _run({"gps_dropout": {"t_start": T0, "duration": 1.5}})
    before, after = _split(clean[0][Topics.GPS], got[Topics.GPS], T0)
    _same(before)
    inside = [(x, y) for x, y in after if x.t < T0 + 1.5]
    outside = [(x, y) for x, y in after if x.t >= T0 + 1.5]
    assert len(inside) >= 14 and outside  # 10 Hz receiver
    for x, y in inside:
        assert x.fix_type == 3 and y.fix_type == 0 and y.satellites == 0
        assert math.isnan(y.latitude_deg) and np.all(np.isnan(y.v_W)) and y.eph == math.inf
    _same(outside)


def test_mag_disturbance_adds_the_field_from_its_start(clean):
    got, _ = _run({"mag_disturbance": {"t_start": T0, "field_T": list(FIELD), "duration": 2.0}})
    before, after = _split(clean[0][Topics.MAGNETOMETER], got[Topics.MAGNETOMETER], T0)
    _same(before)
    inside = [(x, y) for x, y in after if x.t < T0 + 2.0]
    assert len(inside) == 200  # 100 Hz
    for x, y in inside:
        np.testing.assert_allclose(y.m_B - x.m_B, FIELD, rtol=0, atol=1e-18)
    _same([(x, y) for x, y in after if x.t >= T0 + 2.0])


def test_mag_disturbance_of_a_magnitude_draws_its_direction_from_the_seed(clean):
    faults = {"mag_disturbance": {"t_start": T0, "magnitude_T": 1e-4}}
    got, _ = _run(faults)
    again, _ = _run(faults)
    _, after = _split(clean[0][Topics.MAGNETOMETER], got[Topics.MAGNETOMETER], T0)
    d = np.array([y.m_B - x.m_B for x, y in after])
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1e-4, rtol=1e-9)
    np.testing.assert_allclose(d, np.tile(d[0], (len(d), 1)), rtol=1e-9)  # one direction for the whole run
    assert [m.m_B.tobytes() for m in got[Topics.MAGNETOMETER]] == [m.m_B.tobytes() for m in again[Topics.MAGNETOMETER]]
    reseeded = load_scenario("square_sensors", ["seed=1"]).replace(faults=faults)
    rec = _Recorder()
    build_simulation(reseeded, (rec,)).simulator.run(T0 + 0.05)
    clean1 = load_scenario("square_sensors", ["seed=1"])
    rec1 = _Recorder()
    build_simulation(clean1, (rec1,)).simulator.run(T0 + 0.05)
    d1 = rec.got[Topics.MAGNETOMETER][-1].m_B - rec1.got[Topics.MAGNETOMETER][-1].m_B
    assert np.linalg.norm(d1) == pytest.approx(1e-4, rel=1e-9) and not np.allclose(d1, d[0])


def _isa_altitude(p, slp=101325.0, slt=288.15):
    """ISO 2533 troposphere, inverted: written out here, independent of cufund.sensors.barometer."""
    expo = 9.80665 * 0.0289644 / (8.31432 * 0.0065)
    return slt / 0.0065 * (1.0 - (p / slp) ** (1.0 / expo))


def test_baro_step_in_metres_shows_in_the_altitude_by_exactly_the_offset(clean):
    got, _ = _run({"baro_step": {"t_start": T0, "offset_m": BARO_M}})
    before, after = _split(clean[0][Topics.BAROMETER], got[Topics.BAROMETER], T0)
    _same(before)
    for x, y in after:
        assert y.altitude_m - x.altitude_m == pytest.approx(BARO_M, abs=1e-9)
        assert _isa_altitude(y.pressure_pa) == pytest.approx(y.altitude_m, abs=1e-6)  # consistent pressure
        assert y.pressure_pa < x.pressure_pa and y.temperature_k == x.temperature_k


def test_baro_step_in_pascals_shifts_the_pressure_and_the_altitude_it_inverts_to(clean):
    got, _ = _run({"baro_step": {"t_start": T0, "offset_pa": 30.0}})
    before, after = _split(clean[0][Topics.BAROMETER], got[Topics.BAROMETER], T0)
    _same(before)
    for x, y in after:
        assert y.pressure_pa - x.pressure_pa == pytest.approx(30.0, abs=1e-9)
        assert y.altitude_m == pytest.approx(_isa_altitude(y.pressure_pa), abs=1e-6)
        assert x.altitude_m - y.altitude_m == pytest.approx(30.0 / (1.225 * 9.80665), rel=0.01)  # ~2.5 m lower


def test_navigation_faults_parse_round_trip_and_list_in_the_metrics():
    cfg = load_scenario(
        "square_sensors",
        [
            "faults.gps_jump.t_start=3",
            "faults.gps_jump.offset_m=[1, 2, 0]",
            "faults.baro_step.t_start=4",
            "faults.baro_step.offset_pa=-20",
        ],
    )
    assert cfg.faults == (GpsJump(3.0, (1.0, 2.0, 0.0)), BaroStep(4.0, offset_pa=-20.0))
    assert ScenarioConfig.from_dict(cfg.to_dict()) == cfg
    two = parse_faults(
        [
            {"kind": "gps_drift", "t_start": 1, "rate_mps": [0, 0.1, 0]},
            {"kind": "mag_disturbance", "t_start": 2, "magnitude_T": 5e-5, "duration": 3},
        ]
    )
    assert two == (GpsDrift(1.0, (0.0, 0.1, 0.0)), MagDisturbance(2.0, magnitude_T=5e-5, duration=3.0))
    from cufund.scenarios.build import run_scenario

    run = run_scenario(cfg.replace(duration=0.2))
    assert [f["kind"] for f in run.metrics["faults"]] == ["gps_jump", "baro_step"]
    assert run.metrics["faults"][0]["offset_m"] == [1.0, 2.0, 0.0]


@pytest.mark.parametrize(
    "faults, message",
    [
        ({"gps_jump": {"t_start": 1, "offset_m": [1, 2]}}, "faults.gps_jump.offset_m must be 3"),
        ({"gps_jump": {"t_start": 1, "offset_m": [1e5, 0, 0]}}, "faults.gps_jump.offset_m must be at most 10000"),
        ({"gps_drift": {"t_start": 1, "rate_mps": [0, float("inf"), 0]}}, "faults.gps_drift.rate_mps must be 3 finite"),
        ({"gps_dropout": {"t_start": 1, "duration": -1}}, "faults.gps_dropout.duration must be a number of seconds"),
        ({"gps_dropout": {"t_start": -1}}, "faults.gps_dropout.t_start must be a number of seconds"),
        ({"mag_disturbance": {"t_start": 1}}, "faults.mag_disturbance needs exactly one of field_T"),
        ({"mag_disturbance": {"t_start": 1, "field_T": [0, 0, 1e-5], "magnitude_T": 1e-5}}, "exactly one of"),
        ({"mag_disturbance": {"t_start": 1, "magnitude_T": 0}}, "faults.mag_disturbance.magnitude_T must be a number"),
        ({"baro_step": {"t_start": 1}}, "faults.baro_step needs exactly one of offset_m"),
        ({"baro_step": {"t_start": 1, "offset_m": "2"}}, "faults.baro_step.offset_m must be a number"),
        ({"baro_step": {"t_start": 1, "offset_pa": 1e6}}, "faults.baro_step.offset_pa must be a number in [-10000"),
        ({"gps_jump": {"t_start": 1, "offset": [1, 0, 0]}}, "unknown key 'offset' in faults.gps_jump"),
        ({"gps_jump": {"t_start": 1}}, "missing key 'offset_m'"),
        ({"gps_drift": {"t_start": 1, "rate_mps": [0, 0, 0]}}, "faults.gps_drift.rate_mps must not be all zero"),
    ],
)
def test_bad_navigation_faults_are_rejected_by_name(faults, message):
    with pytest.raises(ConfigError) as e:
        load_scenario("square_sensors").replace(faults=faults)
    assert message in str(e.value)


def test_a_navigation_fault_needs_its_sensor():
    cfg = load_scenario("square")
    with pytest.raises(ConfigError, match="gps_jump needs a gps sensor"):
        build_simulation(cfg.replace(faults={"gps_jump": {"t_start": 1, "offset_m": [1, 0, 0]}}))
    with pytest.raises(ConfigError, match="no barometer sensor named 'baro2'"):
        build_simulation(
            load_scenario("square_sensors").replace(
                faults={"baro_step": {"t_start": 1, "offset_m": 1, "sensor": "baro2"}}
            )
        )
