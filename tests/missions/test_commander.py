"""The commander (cufund.missions): commands parsed and validated, the vehicle state machine flown in the lockstep
simulator, checked against ground truth (positions, rotor speeds), never against the commander's own view."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from cufund.core.config import ConfigError
from cufund.core.messages import Topics
from cufund.missions import CommandAck, Commander, parse_command
from cufund.scenarios import ScenarioConfig
from cufund.scenarios.build import build_simulation, run_scenario


def _flight(**planner):
    """A truth-flown cu_astro on the ground at the origin with the commander as planner (no world: fast)."""
    cfg = ScenarioConfig.from_dict(
        {
            "name": "cmd",
            "vehicle": "cu_astro",
            "planner": {"kind": "commander", **planner},
            "controller": "pid",
            "start_p_W": [0.0, 0.0, 0.0],
            "duration": 120.0,
        }
    )
    built = build_simulation(cfg)
    sim = built.simulator
    sim.reset()
    cmd = next(c for c in sim.components if isinstance(c, Commander))
    return sim, cmd


def _p(sim) -> np.ndarray:
    return np.array(sim.vehicle.state.p)


def _rotors(sim) -> np.ndarray:
    return np.array(sim.vehicle.state.rotor_speeds)


def _airborne(sim, cmd, alt=1.5):
    sim.advance_to(0.2)
    assert cmd.apply("arm").result == "accepted"
    assert cmd.apply({"command": "takeoff", "altitude": alt}).result == "accepted"
    sim.advance_to(sim.t + 5.0)


# -- parsing --------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "bad, field",
    [
        ({"command": "fly"}, "command"),
        ({}, "command"),
        (3, "dict"),
        ({"command": "takeoff", "altitude": -1}, "altitude"),
        ({"command": "takeoff", "altitude": "high"}, "altitude"),
        ({"command": "goto"}, "p_W"),
        ({"command": "goto", "p_W": [1, 2]}, "p_W"),
        ({"command": "goto", "p_W": [1, 2, float("nan")]}, "p_W"),
        ({"command": "goto", "p_W": [0, 0, 1], "yaw": "n"}, "yaw"),
        ({"command": "mission_upload", "items": [[0, 0, 1], [1, 1]]}, "items[1]"),
        ({"command": "mission_upload", "items": "abc"}, "items"),
        ({"command": "flight_mode", "mode": "acro"}, "mode"),
        ({"command": "controller", "kind": "mpc"}, "kind"),
        ({"command": "offboard_attitude", "q_WB": [0, 0, 0, 0]}, "q_WB"),
        ({"command": "offboard_velocity"}, "v_W"),
        ({"command": "arm", "altitude": 3}, "altitude"),
        ({"command": "disarm", "force": "yes"}, "force"),
        ({"command": "set_param", "value": 1}, "name"),
    ],
)
def test_bad_commands_name_the_field(bad, field):
    with pytest.raises(ValueError, match=field.replace("[", r"\[").replace("]", r"\]")):
        parse_command(bad)


def test_commands_parse_into_typed_fields():
    c = parse_command(
        {"command": "mission_upload", "items": [[0, 0, 1], {"p_W": [1, 0, 1], "yaw": 0.5, "hold_s": 2}, [2, 0, 1, 1.0]]}
    )
    assert [it.p_W for it in c.items] == [(0, 0, 1), (1, 0, 1), (2, 0, 1)]
    assert c.items[1].yaw == 0.5 and c.items[1].hold_s == 2.0 and c.items[2].yaw == 1.0
    q = parse_command({"command": "offboard_attitude", "q_WB": [2, 0, 0, 0], "thrust": 3}).q_WB
    assert q == (1.0, 0.0, 0.0, 0.0)
    assert parse_command("arm").command == "arm"
    with pytest.raises(ValueError, match="result"):
        CommandAck("arm", "maybe")


def test_script_errors_name_the_entry():
    with pytest.raises(ConfigError, match=r"planner.script\[1\].*altitude"):
        _flight(script=[[0.5, {"command": "arm"}], [1.0, {"command": "takeoff", "altitude": -2}]])


# -- flying ---------------------------------------------------------------------------------------------------
def test_disarmed_rotors_stop_and_takeoff_is_denied():
    sim, cmd = _flight()
    sim.advance_to(1.0)
    assert np.all(_rotors(sim) == 0.0) and abs(_p(sim)[2]) < 1e-6
    ack = cmd.apply({"command": "takeoff"})
    assert ack.result == "denied" and "arm" in ack.message
    assert cmd.events.of_kind("denied")
    assert cmd.apply("hold").result == "accepted"  # PX4 takes Hold on the ground: a no-op
    assert cmd.apply({"command": "goto", "p_W": [0, 0, 1]}).result == "denied"
    sim.advance_to(2.0)
    assert abs(_p(sim)[2]) < 1e-6 and np.all(_rotors(sim) == 0.0)


def test_takeoff_goto_mission_land():
    sim, cmd = _flight()
    _airborne(sim, cmd, 1.5)
    assert abs(_p(sim)[2] - 1.5) < 0.05 and np.linalg.norm(_p(sim)[:2]) < 0.05
    assert cmd.apply("arm").message == "already armed"  # arming in flight: a no-op
    assert cmd.apply("disarm").result == "denied"  # in flight, not forced
    assert cmd.apply({"command": "goto", "p_W": [1.5, -1.0, 2.0]}).result == "accepted"
    sim.advance_to(sim.t + 5.0)
    assert np.linalg.norm(_p(sim) - [1.5, -1.0, 2.0]) < 0.1 and cmd.mode == "hold"
    items = [[1.5, 1.0, 1.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.5]]
    upload = [{"p_W": items[0], "hold_s": 1.0}, *items[1:]]
    assert cmd.apply({"command": "mission_upload", "items": upload}).result == "accepted"
    assert cmd.apply("mission_start").result == "accepted"
    t0 = sim.t
    sim.advance_to(t0 + 12.0)
    reached = cmd.events.of_kind("mission_item_reached")
    assert [e["seq"] for e in reached] == [0, 1, 2]
    assert reached[1]["t"] - reached[0]["t"] >= 1.0 + 1.5  # the hold, then 1.5 m along x at <= 1 m/s per axis
    assert cmd.events.of_kind("mission_complete") and cmd.mode == "hold"
    # truth passes each item, in order
    st = sim.result().states
    m = st["t"] >= t0
    d = [np.linalg.norm(st["p_W"][m] - it, axis=1) for it in items]
    first = [int(np.argmax(di < 0.15)) for di in d]
    assert all(di.min() < 0.15 for di in d) and first == sorted(first)
    assert cmd.apply("land").result == "accepted"
    t_land = sim.t
    sim.advance_to(sim.t + 6.0)
    st = sim.result().states
    low = (st["t"] >= t_land) & (st["p_W"][:, 2] < 0.1)
    assert np.any(low) and np.min(st["v_W"][low, 2]) > -0.45  # the last 10 cm at about land_speed (0.3 m/s)
    assert not cmd.armed and cmd.mode == "idle" and cmd.events.of_kind("landed")
    assert _p(sim)[2] < 0.02 and np.all(_rotors(sim) < 1e-3)  # commanded zero, motor lag decayed
    assert np.linalg.norm(_p(sim)[:2]) < 0.1


def test_rtl_climbs_returns_and_lands_at_home():
    sim, cmd = _flight(rtl_altitude=2.5)
    _airborne(sim, cmd, 1.0)
    cmd.apply({"command": "goto", "p_W": [2.0, 0.0, 1.0]})
    sim.advance_to(sim.t + 4.0)
    t0 = sim.t
    assert cmd.apply("rtl").result == "accepted"
    sim.advance_to(sim.t + 14.0)
    st = sim.result().states
    m = st["t"] >= t0
    p_rtl = st["p_W"][m]
    up = int(np.argmax(p_rtl[:, 2] > 2.4))
    assert p_rtl[up, 2] > 2.4 and p_rtl[up, 0] > 1.8  # climbed to the return height before flying home
    assert not cmd.armed and _p(sim)[2] < 0.02 and np.linalg.norm(_p(sim)[:2]) < 0.1


def test_offboard_stale_setpoints_hold():
    sim, cmd = _flight()
    _airborne(sim, cmd, 1.5)
    for _k in range(50):  # 1 s of setpoints at 50 Hz towards x = 1
        cmd.apply({"command": "offboard_position", "p_W": [1.0, 0.0, 1.5]}, sim.t)
        sim.advance_to(sim.t + 0.02)
    assert cmd.mode == "offboard"
    sim.advance_to(sim.t + 0.4)
    assert cmd.mode == "offboard"
    sim.advance_to(sim.t + 0.3)  # > 0.5 s without a setpoint
    assert cmd.mode == "hold" and "stale" in cmd.events.of_kind("mode")[-1]["message"]
    p_hold = _p(sim)
    sim.advance_to(sim.t + 3.0)
    assert np.linalg.norm(_p(sim) - p_hold) < 0.3 and np.linalg.norm(sim.vehicle.state.v) < 0.05


def test_offboard_velocity_flies_the_velocity():
    sim, cmd = _flight()
    _airborne(sim, cmd, 1.5)
    for _k in range(150):
        cmd.apply({"command": "offboard_velocity", "v_W": [0.5, 0.0, 0.0]}, sim.t)
        sim.advance_to(sim.t + 0.02)
    v = np.array(sim.vehicle.state.v)
    assert abs(v[0] - 0.5) < 0.1 and abs(v[1]) < 0.05 and abs(v[2]) < 0.05  # the velocity PID's overshoot


def test_live_controller_switch_without_a_jump():
    sim, cmd = _flight()
    _airborne(sim, cmd, 1.5)
    t0 = sim.t
    assert cmd.apply({"command": "controller", "kind": "geometric"}).result == "accepted"
    sim.advance_to(sim.t + 3.0)
    assert sim.bus.latest(Topics.RATE_SETPOINT).t < t0 + 0.01  # the pid chain stood down: geometric flew
    assert cmd.apply({"command": "controller", "kind": "pid"}).result == "accepted"
    sim.advance_to(sim.t + 3.0)
    assert sim.bus.latest(Topics.RATE_SETPOINT).t > sim.t - 0.01  # and flies again
    st = sim.result().states
    m = st["t"] >= t0
    assert np.max(np.linalg.norm(st["p_W"][m] - [0.0, 0.0, 1.5], axis=1)) < 0.05


def test_link_loss_holds_then_lands():
    sim, cmd = _flight(link_loss_timeout_s=1.0)
    _airborne(sim, cmd, 1.5)
    cmd.apply({"command": "goto", "p_W": [3.0, 0.0, 1.5]})
    sim.advance_to(sim.t + 0.5)
    cmd.link_lost()
    sim.advance_to(sim.t + 0.1)
    assert cmd.mode == "hold"
    sim.advance_to(sim.t + 8.0)
    assert not cmd.armed and _p(sim)[2] < 0.02 and _p(sim)[0] < 2.0  # never reached the go-to target


def test_forced_disarm_in_flight_stops_the_rotors():
    sim, cmd = _flight()
    _airborne(sim, cmd, 0.3)
    assert cmd.apply({"command": "disarm", "force": True}).result == "accepted"
    w_hover = _rotors(sim).min()
    sim.advance_to(sim.t + 0.01)
    from cufund.core.messages import Topics

    assert np.all(sim.bus.latest(Topics.ACTUATOR_COMMAND).rotor_speeds == 0.0)
    sim.advance_to(sim.t + 0.1)
    assert np.all(_rotors(sim) < 0.2 * w_hover)  # spinning down (motor lag)


def test_params_by_px4_name():
    sim, cmd = _flight()
    assert cmd.apply({"command": "get_params"}).data["MIS_TAKEOFF_ALT"] == 1.5
    assert cmd.apply({"command": "set_param", "name": "MIS_TAKEOFF_ALT", "value": 1.0}).result == "accepted"
    assert cmd.apply({"command": "set_param", "name": "MPC_XY_CRUISE", "value": -1}).result == "denied"
    assert cmd.apply({"command": "set_param", "name": "NOPE", "value": 1}).result == "unsupported"
    sim.advance_to(0.2)
    cmd.apply("arm")
    cmd.apply("takeoff")
    sim.advance_to(sim.t + 5.0)
    assert abs(_p(sim)[2] - 1.0) < 0.05


def test_scripted_scenario_runs_to_the_end():
    cfg = ScenarioConfig.from_dict(
        {
            "name": "scripted",
            "planner": {
                "kind": "commander",
                "script": [
                    [0.2, {"command": "arm"}],
                    [0.5, {"command": "takeoff", "altitude": 1.0}],
                    [4.0, {"command": "goto", "p_W": [1.0, 0.0, 1.0]}],
                    [7.0, {"command": "land"}],
                ],
            },
            "start_p_W": [0.0, 0.0, 0.0],
            "duration": 30.0,
        }
    )
    run = run_scenario(cfg)
    assert run.result.status.value == "completed" and run.result.sim_time_s < 20.0
    p_end = run.result.states["p_W"][-1]
    assert p_end[2] < 0.02 and abs(p_end[0] - 1.0) < 0.1


def test_flight_mode_switches_in_hover_without_a_jump():
    sim, cmd = _flight()
    _airborne(sim, cmd, 1.5)
    t0 = sim.t
    for mode in ("velocity", "attitude", "position"):
        assert cmd.apply({"command": "flight_mode", "mode": mode}).result == "accepted"
        sim.advance_to(sim.t + 1.5)
        assert cmd.flight_mode.value == mode and cmd.mode == "hold"
    st = sim.result().states
    m = st["t"] >= t0
    assert np.max(np.linalg.norm(st["p_W"][m] - [0.0, 0.0, 1.5], axis=1)) < 0.02
    assert np.max(np.linalg.norm(st["v_W"][m], axis=1)) < 0.05


def test_retargeting_in_motion_keeps_the_reference_smooth():
    sim, cmd = _flight()
    _airborne(sim, cmd, 1.5)
    cmd.apply({"command": "goto", "p_W": [3.0, 0.0, 1.5]})
    sim.advance_to(sim.t + 1.5)  # moving at speed
    sp = cmd.setpoint
    assert np.linalg.norm(sp.v_W) > 0.5
    cmd.apply({"command": "goto", "p_W": [0.0, 2.0, 1.5]}, sim.t)
    sim.advance_to(sim.t + 0.005)
    assert np.linalg.norm(cmd.setpoint.v_W - sp.v_W) < 0.05  # no velocity step in the reference
    sim.advance_to(sim.t + 8.0)
    assert np.linalg.norm(_p(sim) - [0.0, 2.0, 1.5]) < 0.1


def test_offboard_attitude_thrust_above_weight_climbs():
    sim, cmd = _flight()
    _airborne(sim, cmd, 1.0)
    weight = sim.vehicle.params.mass * sim.vehicle.params.gravity
    z0 = _p(sim)[2]
    for _k in range(50):  # 1 s level at 1.2 x weight: a = 0.2 g up (less the drag and the thrust lag)
        cmd.apply({"command": "offboard_attitude", "q_WB": [1, 0, 0, 0], "thrust": 1.2 * weight}, sim.t)
        sim.advance_to(sim.t + 0.02)
    assert cmd.flight_mode.value == "attitude"
    dz = _p(sim)[2] - z0
    assert 0.5 * 0.5 * 0.2 * 9.81 < dz < 1.2 * 0.5 * 0.2 * 9.81 and np.linalg.norm(_p(sim)[:2]) < 0.1


def test_same_script_same_flight_bit_for_bit():
    script = [
        [0.2, {"command": "arm"}],
        [0.4, {"command": "takeoff", "altitude": 0.8}],
        [2.0, {"command": "goto", "p_W": [0.5, 0.5, 1.0]}],
    ]
    runs = []
    for _ in range(2):
        sim, _ = _flight(script=script)
        sim.advance_to(3.0)
        runs.append(sim.result().states["p_W"])
    assert np.array_equal(runs[0], runs[1]) and runs[0][-1, 2] > 0.5


def test_goto_with_yaw_turns_smoothly():
    sim, cmd = _flight()
    _airborne(sim, cmd, 1.5)
    t0 = sim.t
    cmd.apply({"command": "goto", "p_W": [0.5, 0.0, 1.5], "yaw": 1.5})
    sim.advance_to(sim.t + 5.0)
    w, x, y, z = sim.vehicle.state.q
    assert abs(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)) - 1.5) < 0.03
    st = sim.result().states
    m = st["t"] >= t0
    assert np.max(np.abs(st["w_B"][m, 2])) < 1.0  # the turn's peak rate is yaw_rate_max = 0.8 rad/s
    assert np.max(np.abs(st["w_B"][m, 2])) > 0.6


_json = hs.recursive(
    hs.none() | hs.booleans() | hs.integers() | hs.floats() | hs.text(max_size=8),
    lambda inner: hs.lists(inner, max_size=5) | hs.dictionaries(hs.text(max_size=8), inner, max_size=5),
    max_leaves=20,
)
_names = hs.sampled_from(
    [
        "arm",
        "disarm",
        "takeoff",
        "goto",
        "mission_upload",
        "flight_mode",
        "controller",
        "offboard_position",
        "offboard_velocity",
        "offboard_attitude",
        "set_param",
        "x",
    ]
)
_fields = hs.dictionaries(
    hs.sampled_from(
        ["altitude", "p_W", "v_W", "yaw", "items", "mode", "kind", "q_WB", "thrust", "name", "value", "force", "other"]
    ),
    _json,
    max_size=4,
)


@settings(max_examples=200, deadline=None)
@given(_names, _fields)
def test_any_json_command_parses_or_raises_value_error(name, fields):
    try:
        c = parse_command({"command": name, **fields})
    except ValueError:
        return
    for v in (c.p_W, c.v_W, c.q_WB):
        assert v is None or all(np.isfinite(v))
    assert c.altitude is None or (np.isfinite(c.altitude) and c.altitude > 0)


def test_mission_start_from_an_item_and_on_the_ground():
    sim, cmd = _flight()
    sim.advance_to(0.2)
    cmd.apply("arm")
    cmd.apply({"command": "mission_upload", "items": [[5.0, 5.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.2]]})
    assert cmd.apply({"command": "mission_start", "seq": 3}).result == "denied"
    assert cmd.apply({"command": "mission_start", "seq": 1}).result == "accepted"  # takes off first
    sim.advance_to(sim.t + 10.0)
    assert [e["seq"] for e in cmd.events.of_kind("mission_item_reached")] == [1, 2]
    st = sim.result().states
    assert np.min(np.linalg.norm(st["p_W"][:, :2] - [5.0, 5.0], axis=1)) > 5.0  # item 0 never approached
    assert np.linalg.norm(_p(sim) - [1.0, 1.0, 1.2]) < 0.1


def test_a_flood_of_refused_commands_is_answered_but_logged_once_a_second():
    sim, cmd = _flight()
    sim.advance_to(0.5)
    n0 = len(cmd.events)
    acks = [cmd.apply({"command": "takeoff"}, 0.5 + k * 1e-3) for k in range(500)]  # 0.5 s of 1000/s
    assert all(a.result == "denied" for a in acks)
    assert len(cmd.events) - n0 == 1
    cmd.apply({"command": "takeoff"}, 1.6)
    assert len(cmd.events) - n0 == 3 and "x499 more" in cmd.events[-2]["message"]


def test_a_command_withdrawn_before_it_is_applied_is_dropped():
    sim, cmd = _flight()
    sim.advance_to(0.2)
    kept, withdrawn = cmd.submit("arm"), cmd.submit({"command": "takeoff", "altitude": 1.0})
    assert withdrawn.cancel()  # its submitter gave up waiting before the commander's next step
    sim.advance_to(0.5)
    assert kept.result(timeout=0).result == "accepted" and withdrawn.cancelled()
    sim.advance_to(3.0)
    assert cmd.armed and abs(_p(sim)[2]) < 1e-3  # armed, never took off
