"""cufund as PX4's SITL simulator, checked from PX4's side of the contract (PX4 itself cannot be installed here):
a pymavlink client plays ``simulator_mavlink`` over TCP — connects, heartbeats, reads HIL_SENSOR / HIL_GPS /
HIL_STATE_QUATERNION and answers with HIL_ACTUATOR_CONTROLS — and the checks are physical facts (gravity in
FRD, the ISA, the Earth's field, which way a vehicle yaws or rolls when PX4's motors 1..4 speed up)."""

from __future__ import annotations

import math
import threading
from contextlib import contextmanager

import numpy as np
import pytest

from cufund.apps.mavlink.frames import GeodeticOrigin, deg_to_e7
from cufund.apps.mavlink.px4_airframe import Px4Airframe
from cufund.apps.mavlink.px4_harness import Px4Harness
from cufund.apps.mavlink.px4_links import TcpServerLink
from cufund.apps.mavlink.px4_sim import (
    PX4_SENSOR_RATES,
    Px4BridgeParams,
    Px4SimulatorBridge,
    px4_scenario,
    sensor_instances,
)
from cufund.core.config import ConfigError
from cufund.scenarios import ScenarioConfig, load_scenario
from cufund.vehicle.presets import iris
from mavlink_support import px4_sim_cli

NOISY = {"imu": "icm42688p", "magnetometer": "magnetometer", "barometer": "ms5611", "gps": "ublox_m8n"}
IDEAL = {"imu": "ideal_imu", "magnetometer": "magnetometer", "barometer": "ideal_barometer", "gps": "ideal_gps"}
U_HOVER = (iris().hover_rotor_speed - 100.0) / 1000.0  # iris: omega = 1000 u + 100 rad/s
STEP_US = 4000


def _config(sensors=NOISY, seed=3):
    return ScenarioConfig.from_dict(
        {"name": "px4_test", "vehicle": "iris", "seed": seed, "duration": 60.0, "sensors": dict(sensors)}
    )


@contextmanager
def _serve(config=None, params=None, duration=30.0, hover_at=None, v_W=None):
    """A bridge on a free port, run in a thread; yields (bridge, harness, outcome)."""
    params = params or Px4BridgeParams(speed=None, wait_first_controls=True)
    bridge = Px4SimulatorBridge(config or _config(), TcpServerLink("127.0.0.1", 0), params)
    if hover_at is not None:
        bridge.simulator.vehicle.hover(np.asarray(hover_at, dtype=float))
    if v_W is not None:
        bridge.simulator.vehicle.state.v[:] = v_W
    outcome: dict = {}

    def run():
        try:
            outcome["result"] = bridge.run(duration=duration, connect_timeout=10.0)
        except BaseException as e:
            outcome["error"] = e

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    harness = Px4Harness.tcp("127.0.0.1", bridge.port_number)
    try:
        yield bridge, harness, outcome
    finally:
        harness.close()
        thread.join(10.0)
        bridge.close()
        assert not thread.is_alive(), "the bridge did not stop when PX4 left"
        if "error" in outcome:
            raise outcome["error"]


def _fly(harness, n, u, armed=True):
    """n lockstep periods answering each HIL_SENSOR with the same controls; returns the steps."""
    steps = []
    for _ in range(n):
        s = harness.step(timeout=10.0)
        steps.append(s)
        harness.controls(u(s) if callable(u) else u, armed, s.sensor.time_usec)
    return steps


def _isa_pressure_hpa(h_m):  # the 1976 standard atmosphere's troposphere, written out independently
    return 1013.25 * (1.0 - 0.0065 * h_m / 288.15) ** (9.80665 * 0.0289644 / (8.3144598 * 0.0065))


# --- the scenario PX4 gets --------------------------------------------------------------------------------------


def test_px4_scenario_strips_flight_software_and_sets_px4_rates():
    cfg = px4_scenario(load_scenario("square_sensors"))
    for group in ("estimator", "mapper", "planner", "controller", "mission"):
        assert getattr(cfg, group) is None
    by_type = {s.sensor_type: s for s in cfg.sensors.values()}
    assert {k: by_type[k].params.rate_hz for k in PX4_SENSOR_RATES} == PX4_SENSOR_RATES
    assert by_type["imu"].kind == "icm42688p" and by_type["gps"].kind == "ublox_m8n"  # the scenario's own models
    bare = px4_scenario(ScenarioConfig.from_dict({"name": "bare", "vehicle": "iris"}))
    assert sorted(s.sensor_type for s in bare.sensors.values()) == sorted(PX4_SENSOR_RATES)


def test_airframe_mapping_and_motor_order():
    a = Px4Airframe.iris()
    np.testing.assert_allclose(a.rotor_speeds([0.0, 0.5, 1.0, 0.25], armed=True), [100.0, 600.0, 1100.0, 350.0])
    np.testing.assert_array_equal(a.rotor_speeds([0.7] * 4, armed=False), [0.0] * 4)
    np.testing.assert_array_equal(a.rotor_speeds([np.nan, 0.0, 0.0, 0.0], armed=True)[0], 0.0)
    # PX4 quad_x numbering equals cufund's "x" layout; quad_+ is a permutation found from the geometry
    np.testing.assert_array_equal(a.rotor_of_output(iris()), [0, 1, 2, 3])
    import dataclasses

    plus = dataclasses.replace(iris(), name="plus", layout="+")
    np.testing.assert_array_equal(Px4Airframe.for_vehicle(plus).rotor_of_output(plus), [1, 3, 0, 2])
    with pytest.raises(ConfigError, match="no matching rotor"):
        Px4Airframe(geometry="quad_+").rotor_of_output(iris())
    with pytest.raises(ConfigError, match="input_scaling"):
        Px4Airframe(input_scaling=(1.0, 2.0))


# --- the wire contract ------------------------------------------------------------------------------------------


def test_free_run_until_first_controls_then_lockstep():
    """PX4 starts only once time flows: sensors stream before any controls; after the first controls every
    HIL_SENSOR waits for the answer to the previous one."""
    params = Px4BridgeParams(speed=4.0, controls_timeout_s=5.0)
    with _serve(params=params) as (bridge, px4, _):
        px4.heartbeat()
        first = [px4.step() for _ in range(20)]  # nobody answered
        stamps = [s.sensor.time_usec for s in first]
        assert stamps == list(range(STEP_US, 21 * STEP_US, STEP_US))  # one period in, as Gazebo: never 0
        hb = [m for s in first for m in s.other if m.get_type() == "HEARTBEAT"]
        assert len(hb) == 1 and hb[0].type == 0 and hb[0].autopilot == 8  # generic, not an autopilot
        px4.controls([0.0] * 4, armed=False)
        # the stream stops once the bridge has seen controls: drain what was in flight
        seen = []
        while True:
            msgs = px4.poll(0.5)
            if not msgs:
                break
            seen += [m for m in msgs if m.get_type() == "HIL_SENSOR"]
        last = seen[-1].time_usec if seen else stamps[-1]
        for _k in range(3):  # now strictly one HIL_SENSOR per answer
            px4.controls([0.0] * 4, armed=False, time_usec=last)
            s = px4.step(timeout=5.0)
            assert s.sensor.time_usec == last + STEP_US
            last = s.sensor.time_usec
            assert [m for m in px4.poll(0.3) if m.get_type() == "HIL_SENSOR"] == []
        assert bridge.stats["heartbeats_received"] == 1


def test_hil_sensor_units_frames_and_bits_at_rest():
    with _serve() as (bridge, px4, _):
        steps = _fly(px4, 250, [0.0] * 4, armed=False)  # 1 s on the ground, disarmed
    sensors = [s.sensor for s in steps]
    assert [m.time_usec for m in sensors] == list(range(STEP_US, 251 * STEP_US, STEP_US))
    assert all(m.id == 0 for m in sensors)
    bits = np.array([m.fields_updated for m in sensors])
    assert np.all(bits & 0x3F == 0x3F)  # accel + gyro every period (IMU at 250 Hz)
    assert np.count_nonzero(bits[:-1] & 0x1C0 == 0x1C0) == 100  # magnetometer at 100 Hz (samples 0 .. 0.99 s)
    assert np.count_nonzero(bits[:-1] & 0x1A00 == 0x1A00) == 50  # barometer at 50 Hz
    assert bits[0] == 0x1BFF
    acc = np.array([[m.xacc, m.yacc, m.zacc] for m in sensors])
    gyro = np.array([[m.xgyro, m.ygyro, m.zgyro] for m in sensors])
    np.testing.assert_allclose(acc.mean(0), [0.0, 0.0, -9.80665], atol=0.7)  # icm42688p turn-on bias 0.2 m/s^2/axis
    np.testing.assert_allclose(gyro.mean(0), 0.0, atol=0.05)
    assert acc.std(0).max() > 1e-4  # the sensor model's noise, not truth
    mag = np.array([[m.xmag, m.ymag, m.zmag] for m in sensors if m.fields_updated & 0x1C0])
    field = bridge.config.sensors["magnetometer"].params.earth
    np.testing.assert_allclose(np.linalg.norm(mag, axis=1).mean(), field.intensity_T * 1e4, rtol=0.02)  # gauss
    # level, nose east (cufund's identity attitude): PX4's magnetic heading atan2(-y, x) = 90 deg - declination,
    # and the field dips down (+z FRD) with positive inclination
    heading = math.degrees(math.atan2(-mag[:, 1].mean(), mag[:, 0].mean()))
    assert heading == pytest.approx(90.0 - field.declination_deg, abs=2.0)
    assert mag[:, 2].mean() > 0
    baro = [m for m in sensors if m.fields_updated & 0x1A00]
    home_alt = bridge.config.sensors["barometer"].params.home_altitude_m
    p = np.array([m.abs_pressure for m in baro])
    assert p.mean() == pytest.approx(_isa_pressure_hpa(home_alt), abs=3.0)  # ms5611 turn-on offset 1 hPa
    for m in baro:  # pressure_alt is the ISA altitude of abs_pressure; temperature the ISA's at home, in degC
        assert m.abs_pressure == pytest.approx(_isa_pressure_hpa(m.pressure_alt), abs=2e-3)
        assert m.temperature == pytest.approx(15.0 - 0.0065 * home_alt, abs=0.05)


def test_hover_thrust_holds_more_thrust_climbs_disarmed_falls():
    with _serve(config=_config(IDEAL), hover_at=(0.0, 0.0, 20.0)) as (bridge, px4, _):
        px4.request_state(5000)
        home_mm = round(bridge.origin.alt_m * 1000)

        def alt(steps):
            return [(st.alt - home_mm) / 1000.0 for s in steps for st in s.state]

        hover = _fly(px4, 250, [U_HOVER] * 4)
        h = alt(hover)
        assert 199 <= len(h) <= 200  # 200 Hz as asked (5000 us), only after the request
        # (the motors idle for the first period, before PX4's first answer: a few cm of sag, then a steady state)
        assert max(abs(x - 20.0) for x in h) < 0.1
        vz = [st.vz for s in hover[125:] for st in s.state]
        assert max(vz) - min(vz) <= 1  # [cm/s]: hover thrust exactly holds the weight
        climb = _fly(px4, 125, [U_HOVER + 0.1] * 4)
        hc = alt(climb)
        assert hc[-1] - h[-1] > 0.2 and climb[-1].state[-1].vz < -50  # NED z decreases: vz [cm/s] negative
        assert np.mean([s.sensor.zacc for s in climb[-50:]]) < -9.80665 - 1.0  # more thrust: more specific force
        hp0 = np.mean([s.sensor.abs_pressure for s in hover if s.sensor.fields_updated & 0x1A00])
        hp1 = climb[-1].sensor.abs_pressure
        home = bridge.config.sensors["barometer"].params.home_altitude_m
        expected = _isa_pressure_hpa(hc[-1] + home) - _isa_pressure_hpa(float(np.mean(h)) + home)
        assert hp1 - hp0 == pytest.approx(expected, abs=0.03)  # the climb, seen by the barometer as the ISA says
        fall = _fly(px4, 100, [0.9] * 4, armed=False)  # outputs ignored while disarmed
        assert fall[-1].state[-1].vz > 100


@pytest.mark.parametrize(
    "name, u, axis, sign",
    [
        ("yaw right: CCW motors 1, 2 faster", [0.1, 0.1, -0.1, -0.1], 2, +1),
        ("roll right: left motors 2, 3 faster", [-0.03, 0.03, 0.03, -0.03], 0, +1),
        ("pitch up: front motors 1, 3 faster", [0.03, -0.03, 0.03, -0.03], 1, +1),
    ],
)
def test_motor_order_and_gyro_signs(name, u, axis, sign):
    with _serve(config=_config(IDEAL), hover_at=(0.0, 0.0, 30.0)) as (_, px4, outcome):
        px4.request_state(4000)
        steps = _fly(px4, 50, [U_HOVER + du for du in u])
    s = steps[-1].sensor
    assert sign * [s.xgyro, s.ygyro, s.zgyro][axis] > 0.2, name
    state = steps[-1].state[-1]
    assert sign * [state.rollspeed, state.pitchspeed, state.yawspeed][axis] > 0.2  # ground truth agrees
    w_B = outcome["result"].states["w_B"][-1]  # cufund's FLU body rate: y and z flip
    assert sign * w_B[axis] * (1 if axis == 0 else -1) > 0.2


def test_hil_gps_rate_and_encoding():
    cfg = _config(IDEAL)
    with _serve(config=cfg, hover_at=(0.0, 0.0, 50.0), v_W=(1.0, 2.0, 0.0)) as (bridge, px4, _):
        steps = _fly(px4, 500, [U_HOVER] * 4)  # 2 s
    fixes = [g for s in steps[:-1] for g in s.gps]
    assert len(fixes) == 10  # 5 Hz: measured at 0, 0.2, .. 1.8 s
    t = np.array([s.sensor.time_usec for s in steps if s.gps])
    assert t[0] == STEP_US
    np.testing.assert_array_equal(np.diff(t[1:]), 200_000)
    home = GeodeticOrigin.from_geo_point(cfg.sensors["gps"].params.home)
    assert bridge.origin == home
    g = fixes[0]  # measured at t = 0: the origin, 50 m up
    assert (g.lat, g.lon) == (deg_to_e7(home.lat_deg), deg_to_e7(home.lon_deg))
    assert g.alt == round((home.alt_m + 50.0) * 1000)
    assert g.fix_type == 3 and g.satellites_visible == cfg.sensors["gps"].params.satellites
    assert (g.vn, g.ve) == (200, 100)  # ENU (1, 2) m/s is 2 m/s north, 1 m/s east, in cm/s
    assert g.vel == 224 and g.cog == pytest.approx(2657, abs=2)  # atan2(east, north) in cdeg
    last = fixes[-1]  # 1.8 s later: moved north twice as far as east (rotor drag slows both alike)
    north, east, _ = home.lla_to_ned([last.lat * 1e-7, last.lon * 1e-7, last.alt * 1e-3])
    assert north > 1.5 and east / north == pytest.approx(0.5, abs=0.03)


def test_hil_state_quaternion_only_on_request():
    with _serve(config=_config(IDEAL), hover_at=(0.0, 0.0, 10.0)) as (_, px4, _o):
        early = _fly(px4, 50, [U_HOVER] * 4)
        assert sum(len(s.state) for s in early) == 0
        px4.request_state(0)  # 0: the default rate, every period
        steps = _fly(px4, 50, [U_HOVER] * 4)
        acks = [m for s in steps for m in s.other if m.get_type() == "COMMAND_ACK"]
        assert len(acks) == 1 and acks[0].command == 511 and acks[0].result == 0
        assert sum(len(s.state) for s in steps[1:]) == 49
        st = steps[-1].state[-1]
        s = math.sqrt(0.5)
        np.testing.assert_allclose(st.attitude_quaternion, [s, 0, 0, s], atol=1e-3)  # level, nose east: yaw 90
        px4.send(px4.mav.command_long_encode(0, 0, 511, 0, 115, -1, 0, 0, 0, 0, 0))  # -1: stop
        later = _fly(px4, 20, [U_HOVER] * 4)
        assert sum(len(s.state) for s in later[1:]) == 0
        px4.send(px4.mav.command_long_encode(0, 0, 511, 0, 33, 1000, 0, 0, 0, 0, 0))  # not ours to give
        nack = [m for s in _fly(px4, 3, [U_HOVER] * 4) for m in s.other if m.get_type() == "COMMAND_ACK"]
        assert nack[0].result == 3  # MAV_RESULT_UNSUPPORTED
        px4.send(px4.mav.command_long_encode(0, 0, 511, 0, float("nan"), float("nan"), 0, 0, 0, 0, 0))
        nan = [m for s in _fly(px4, 3, [U_HOVER] * 4) for m in s.other if m.get_type() == "COMMAND_ACK"]
        assert nan[0].result == 3


def _record(seed):
    with _serve(config=_config(NOISY, seed=seed)) as (_, px4, _o):
        steps = _fly(px4, 200, lambda s: [0.75 + 0.01 * ((s.sensor.time_usec // STEP_US) % 3)] * 4)
    return [bytes(s.sensor.get_msgbuf()) for s in steps] + [bytes(g.get_msgbuf()) for s in steps for g in s.gps]


def test_deterministic_for_a_seed():
    a, b, c = _record(7), _record(7), _record(8)
    assert a == b
    assert a != c


def test_malformed_input_is_counted_and_survived():
    with _serve(hover_at=(0.0, 0.0, 10.0)) as (bridge, px4, _):
        s = px4.step()
        bad = bytearray(px4.mav.hil_actuator_controls_encode(0, [0.9] * 16, 129, 1).pack(px4.mav))
        bad[-1] ^= 0xFF  # bad CRC
        unknown = bytearray(px4.mav.heartbeat_encode(2, 12, 0, 0, 0).pack(px4.mav))
        unknown[7:10] = b"\x39\x30\x00"  # message id 12345: not in the dialect (its CRC no longer matches either)
        px4._write(b"\x00garbage\xfd\x01" + bytes(bad) + bytes(unknown))
        px4.controls([np.nan, np.nan, np.nan, np.nan], armed=True, time_usec=s.sensor.time_usec)
        nxt = px4.step()
        assert nxt.sensor.time_usec == s.sensor.time_usec + STEP_US
        assert bridge.stats["bad_packets"] >= 2
        np.testing.assert_array_equal(bridge._command(0.004), 0.0)  # NaN outputs: motors stopped
        px4.controls([U_HOVER] * 4, time_usec=nxt.sensor.time_usec)
        _fly(px4, 5, [U_HOVER] * 4)
        px4.step()  # the last answer has been taken
        assert bridge.stats["controls"] == 7 and bridge.stats["controls_timeouts"] == 0


def test_px4_leaving_ends_the_run():
    with _serve() as (_, px4, outcome):
        _fly(px4, 10, [0.0] * 4, armed=False)
        px4.close()
    assert outcome["result"].message == "PX4 closed the connection"
    assert outcome["result"].sim_time_s == pytest.approx(11 * STEP_US * 1e-6, abs=1e-9)  # the 11th went unanswered


def test_pd_hover_loop_closed_through_the_bridge():
    """A small attitude + altitude PD loop on PX4's side, flying through HIL_STATE_QUATERNION and PX4's motor
    order: it only holds if frames, mixing order and thrust mapping are all right."""
    h_ref = 2.0

    def law(step):
        if not step.state:
            return law.last
        st = step.state[-1]
        w, x, y, z = st.attitude_quaternion
        roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
        pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
        yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        h = (st.alt - law.home_mm) / 1000.0
        thrust = U_HOVER + 0.16 * (h_ref - h) - 0.12 * (-st.vz / 100.0)
        tr = (-25 * roll - 8 * st.rollspeed) / 230.0
        tp = (-25 * pitch - 8 * st.pitchspeed) / 230.0
        ty = (-4 * math.remainder(yaw - math.pi / 2, 2 * math.pi) - 2 * st.yawspeed) / 40.0
        law.last = [thrust - tr + tp + ty, thrust + tr - tp + ty, thrust + tr + tp - ty, thrust - tr - tp - ty]
        return law.last

    law.last = [0.0] * 4
    with _serve(config=_config(NOISY)) as (bridge, px4, outcome):
        law.home_mm = round(bridge.origin.alt_m * 1000)
        px4.request_state(5000)
        _fly(px4, 1250, law)  # 5 s: take off from the ground and hold 2 m
    states = outcome["result"].states
    last = states["t"] >= states["t"][-1] - 1.0
    z = states["p_W"][last, 2]
    assert np.all(np.abs(z - h_ref) < 0.1)
    q = states["q_WB"][last]
    tilt = np.degrees(np.arccos(np.clip(1 - 2 * (q[:, 1] ** 2 + q[:, 2] ** 2), -1, 1)))
    assert tilt.max() < 3.0
    assert np.abs(states["p_W"][last, :2]).max() < 0.3


def test_cli_serves_sitl_on_4560_plus_instance(capsys):
    thread, code, port = px4_sim_cli(0.2)
    px4 = Px4Harness.tcp("127.0.0.1", port, timeout=20.0)
    try:
        px4.heartbeat()
        stamps = []
        while True:
            try:
                s = px4.step(timeout=10.0)
                stamps.append(s.sensor.time_usec)
                # until PX4's first controls the world runs on without waiting: on a busy machine the run may end
                # (and the bridge hang up) before the last answers are written
                px4.controls([0.0] * 4, armed=False, time_usec=s.sensor.time_usec)
            except ConnectionError:
                break
    finally:
        px4.close()
        thread.join(20.0)
    assert code["exit"] == 0
    assert stamps == list(range(STEP_US, 200_000, STEP_US))
    out = capsys.readouterr().out
    assert f"tcp://127.0.0.1:{port} (SITL, lockstep)" in out and "status: completed (duration elapsed)" in out


def test_fuzzed_bytes_and_nonsense_commands_never_stop_the_world():
    rng = np.random.default_rng(11)
    # a false frame start in the noise may swallow the controls behind it (as in PX4's own parser): the bridge
    # then steps on after controls_timeout_s, here short
    params = Px4BridgeParams(speed=None, wait_first_controls=True, controls_timeout_s=0.05)
    with _serve(params=params, hover_at=(0.0, 0.0, 10.0)) as (bridge, px4, _):
        for k in range(40):
            s = px4.step()
            noise = rng.integers(0, 256, size=int(rng.integers(1, 600)), dtype=np.uint8).tobytes()
            if k % 3 == 0:
                noise = noise.replace(b"\xfd", b"\xfe") + b"\xfd"  # a frame start cut short by the next frame
            px4._write(noise)
            if k == 5:
                px4.send(px4.mav.command_long_encode(0, 0, 511, 0, float("nan"), float("nan"), 0, 0, 0, 0, 0))
            px4.controls([U_HOVER] * 4, time_usec=s.sensor.time_usec)
        assert px4.step().sensor.time_usec >= 40 * STEP_US
        assert bridge.stats["bad_packets"] > 0 and bridge.stats["controls"] >= 10
        assert bridge.stats["controls"] + bridge.stats["controls_timeouts"] >= 40


def test_imu_mounting_is_undone_into_the_body_frame():
    """An IMU mounted yawed 90 degrees (T_BI) still yields body-FRD rates: a roll to the right is +xgyro."""
    s45 = math.sqrt(0.5)
    sensors = {**IDEAL, "imu": {"kind": "ideal_imu", "T_BI": {"p": [0.0, 0.0, 0.0], "q": [s45, 0.0, 0.0, s45]}}}
    with _serve(config=_config(sensors), hover_at=(0.0, 0.0, 30.0)) as (_, px4, _o):
        steps = _fly(px4, 50, [U_HOVER - 0.03, U_HOVER + 0.03, U_HOVER + 0.03, U_HOVER - 0.03])
    first, last = steps[0].sensor, steps[-1].sensor
    assert abs(first.xacc) < 1e-6 and abs(first.yacc) < 1e-6 and first.zacc < -4.0  # thrust along body z only
    assert last.xgyro > 0.2 and abs(last.ygyro) < 0.05 * last.xgyro


def test_several_sensors_become_px4_sensor_instances():
    """A second IMU and barometer go out as HIL_SENSOR instance 1 (before instance 0, which closes the period and
    drives PX4's lockstep); the sensor named after its type is instance 0 wherever it is declared."""
    sensors = {"imu_b": "bmi088", **NOISY, "baro_b": "ideal_barometer"}
    cfg = _config(sensors)
    assert sensor_instances(cfg, "imu") == ["imu", "imu_b"] and sensor_instances(cfg, "gps") == ["gps"]
    with _serve(config=cfg) as (_, px4, _o):
        steps = _fly(px4, 50, [0.0] * 4, armed=False)
    assert all(len(s.sensors) == 1 and s.sensors[0].id == 1 for s in steps)
    assert all(s.sensors[0].time_usec == s.sensor.time_usec for s in steps)
    bits = np.array([s.sensors[0].fields_updated for s in steps])
    assert np.all(bits & 0x3F == 0x3F) and not np.any(bits & 0x1C0)  # its IMU every period, no magnetometer
    assert np.count_nonzero(bits[:-1] & 0x1A00) == 10  # its barometer at 50 Hz
    z1 = np.mean([s.sensors[0].zacc for s in steps])
    z0 = np.mean([s.sensor.zacc for s in steps])
    assert z1 == pytest.approx(-9.80665, abs=0.6) and z0 == pytest.approx(-9.80665, abs=0.6) and z0 != z1
    too_many = _config({**NOISY, "imu_2": "bmi088", "imu_3": "bmi088", "imu_4": "bmi088"})
    with pytest.raises(ConfigError, match="at most 3 imu"):
        px4_scenario(too_many)
