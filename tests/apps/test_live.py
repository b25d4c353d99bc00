"""LiveRun: a scenario flown in a background thread, paced to the wall clock, commanded from other threads. Coarse
timing bounds only (3x and more); every wait is bounded."""

from __future__ import annotations

import json
import math
import threading
import time

import pytest

from cufund.apps.live import LiveRun
from cufund.core.components import Component

FAST = {
    "name": "live",
    "vehicle": "cu_astro",
    "planner": {"kind": "commander"},
    "controller": "pid",
    "start_p_W": [0.0, 0.0, 0.0],
    "duration": 600.0,
}


def _sim_rate(run: LiveRun, wall_s: float) -> float:
    t0, w0 = run.telemetry()["t"], time.perf_counter()
    time.sleep(wall_s)
    return (run.telemetry()["t"] - t0) / (time.perf_counter() - w0)


def test_paced_at_speed_one_faster_at_inf_and_paused():
    with LiveRun(FAST, speed=1.0) as run:
        time.sleep(0.3)
        r1 = _sim_rate(run, 1.5)
        assert 1 / 3 < r1 < 3.0
        run.set_speed(0.25)
        r_slow = _sim_rate(run, 1.5)
        assert 0.25 / 3 < r_slow < 0.75
        run.set_speed(math.inf)
        r_inf = _sim_rate(run, 1.5)
        assert r_inf > 2 * r_slow  # unpaced: as fast as the CPU goes (this scenario: several x real time)
        run.pause()
        time.sleep(0.2)
        t_paused = run.telemetry()["t"]
        time.sleep(0.5)
        assert run.telemetry()["t"] == t_paused and run.telemetry()["paused"]
        run.resume()
        assert run.wait_until(lambda s: s["t"] > t_paused, 5.0)
        with pytest.raises(ValueError, match="speed"):
            run.set_speed(50)
    assert not run.running and run.ended == "stopped"


def test_vehicle_scenario_flies_from_commands_submitted_by_other_threads():
    with LiveRun("vehicle", speed=math.inf) as run:
        assert run.commander is not None and run.commander.params.script == ()  # a live vehicle waits
        acks: list = []

        def client(cmd):
            acks.append(run.submit(cmd).result(timeout=10))

        t = threading.Thread(target=client, args=({"command": "arm"},))
        t.start()
        t.join(10)
        assert acks and acks[0].result == "accepted"
        with pytest.raises(ValueError, match="altitude"):
            run.submit({"command": "takeoff", "altitude": "up"})
        assert run.submit({"command": "takeoff", "altitude": 1.2}).result(timeout=10).ok
        assert run.wait_until(lambda s: s["mode"] == "hold", 60)
        tel = run.telemetry(events_since=0)
        assert json.loads(json.dumps(tel, allow_nan=False)) == tel  # JSON as it is: no numpy types, no NaN
        assert abs(tel["truth_p_W"][2] - 1.2) < 0.05  # ground truth, not the commander's view
        assert tel["estimator"]["ok"] and tel["odometry_error_m"] < 0.05 and 0 < tel["thrust_margin"] < 1
        assert [e["kind"] for e in tel["events"]][:2] == ["armed", "mode"]
        assert run.latest("/sensors/imu") is not None
        reads = run.simulator.views["commander"].reads
        assert "/estimator/odometry" in reads and not any(r.startswith("/truth/") for r in reads)
        seen: list = []
        remove = run.add_listener(seen.append, rate_hz=20)
        assert run.submit({"command": "land"}).result(timeout=10).ok
        assert run.wait_until(lambda s: not s["armed"], 60)
        remove()
        assert len(seen) >= 2 and seen[-1]["t"] > seen[0]["t"]
        assert run.telemetry()["truth_p_W"][2] < 0.02


class _Faulty(Component):
    name = "faulty"
    rate_hz = 10.0

    def step(self, t, bus):
        if t > 0.5:
            raise RuntimeError("boom")


def test_component_exception_becomes_an_event_and_the_run_goes_on():
    with LiveRun(FAST, speed=math.inf, extra_components=(_Faulty(),)) as run:
        assert run.wait_until(lambda s: s["t"] > 2.0, 30)
        errors = run.events.of_kind("error")
        assert errors and "faulty" in errors[0]["message"] and "boom" in errors[0]["message"]
        assert run.running and run.ended is None
        assert run.submit({"command": "arm"}).result(timeout=10).result == "accepted"


def test_crash_ends_the_run_cleanly_with_an_event():
    with LiveRun(FAST, speed=math.inf) as run:
        run.submit({"command": "arm"}).result(timeout=10)
        run.submit({"command": "takeoff", "altitude": 2.0}).result(timeout=10)
        assert run.wait_until(lambda s: s["mode"] == "hold", 60)
        assert run.submit({"command": "disarm", "force": True}).result(timeout=10).ok
        assert run.wait_until(lambda s: s["ended"] is not None, 30)
        assert run.events.of_kind("crash") and "crashed" in run.ended
        assert not run.running
        late = run.submit({"command": "arm"}).result(timeout=1)
        assert late.result == "failed"


def test_controller_gains_by_px4_name_in_flight():
    with LiveRun(FAST, speed=math.inf) as run:
        params = run.submit({"command": "get_params"}).result(timeout=10).data
        assert params["MPC_XY_P"] == 0.95 and abs(params["MPC_TILTMAX_AIR"] - 45.0) < 1e-9
        assert params["GEO_K_X"] > 0 and params["MIS_TAKEOFF_ALT"] == 1.5
        ack = run.submit({"command": "set_param", "name": "MPC_TILTMAX_AIR", "value": 30.0}).result(timeout=10)
        assert ack.result == "accepted"
        pos = next(c for c in run.simulator.components if type(c).__name__ == "PositionController")
        assert abs(pos.gains.tilt_max - math.radians(30.0)) < 1e-12
        bad = run.submit({"command": "set_param", "name": "MPC_TILTMAX_AIR", "value": 120.0}).result(timeout=10)
        assert bad.result == "denied" and "tilt_max" in bad.message
        assert abs(pos.gains.tilt_max - math.radians(30.0)) < 1e-12


def test_commands_are_answered_while_paused_and_the_plan_is_shown():
    with LiveRun(FAST, speed=math.inf) as run:
        assert run.wait_until(lambda s: s["t"] > 0.2, 10)
        run.pause()
        time.sleep(0.2)
        t = run.telemetry()["t"]
        assert run.submit({"command": "arm"}).result(timeout=5).result == "accepted"
        assert run.submit({"command": "takeoff", "altitude": 1.0}).result(timeout=5).ok
        tel = run.telemetry()
        assert tel["t"] == t and tel["armed"] and tel["mode"] == "takeoff"
        assert tel["plan_W"] == [[0.0, 0.0, 1.0]]
        run.resume()
        assert run.wait_until(lambda s: s["mode"] == "hold", 30)
        assert run.submit({"command": "rtl"}).result(timeout=5).ok
        plan = run.telemetry()["plan_W"]
        assert plan[-1] == [0.0, 0.0, 0.0] and len(plan) == 3  # climb, home, touch down


def test_bad_arguments_fail_before_anything_runs():
    from cufund.core.config import ConfigError

    with pytest.raises(ValueError, match="speed"):
        LiveRun(FAST, speed=0)
    with pytest.raises(ConfigError, match="planner.takeoff_altitude"):
        LiveRun("vehicle", overrides=["planner.takeoff_altitude=-1"])
    with pytest.raises(TypeError, match="scenario_or_config"):
        LiveRun(42)
    assert not [t for t in threading.enumerate() if t.name == "cufund-live"]
