"""LiveFleet: every vehicle advanced together, each commanded and watched as a single live run."""

from __future__ import annotations

import time

import pytest
from test_fleet_mavlink import fleet_config

from cufund.apps.mavlink.fleet_live import LiveFleet


def test_vehicles_advance_together_and_answer_for_themselves():
    with LiveFleet(fleet_config(2), speed=float("inf")) as live:
        uav1, uav2 = live.vehicle("uav1"), live.vehicle("uav2")
        assert uav2.submit({"command": "arm"}).result(timeout=5).result == "accepted"
        assert uav2.submit({"command": "takeoff", "altitude": 1.5}).result(timeout=5).result == "accepted"
        assert uav2.wait_until(
            lambda t: t.get("p_W") is not None and t["p_W"][2] > 1.4, 20.0
        )  # (none before the first state)
        t1, t2 = uav1.telemetry(), uav2.telemetry()
        assert not t1["armed"] and t2["armed"]
        assert t1["p_W"][:2] == pytest.approx([0.0, 0.0], abs=0.05) and t1["p_W"][2] < 0.1
        assert t2["p_W"][:2] == pytest.approx([3.0, 0.0], abs=0.2)
        acks = live.submit_all({"command": "land"})
        assert set(acks) == {"uav1", "uav2"}
        assert acks["uav2"].result(timeout=5).result == "accepted"
        live.pause()
        time.sleep(0.1)
        t_paused = live.t
        time.sleep(0.3)
        assert live.t == t_paused and uav1.paused and uav2.paused
        live.resume()
        with pytest.raises(KeyError, match="no vehicle 'uav9'"):
            live.vehicle("uav9")
    sims = [v.simulator for v in live.vehicles.values()]
    assert sims[0].t == sims[1].t == live.t  # one clock: neither ran ahead
    assert live.ended == "stopped" and uav1.ended == "stopped"
    ack = uav1.submit({"command": "arm"}).result(timeout=1)
    assert ack.result == "failed" and "ended" in ack.message


def test_a_single_vehicle_scenario_is_not_a_fleet():
    with pytest.raises(ValueError, match="one vehicle"):
        LiveFleet("vehicle", start=False)
    with pytest.raises(ValueError, match="speed"):
        LiveFleet(fleet_config(1), speed=0.0)


def test_scripted_commands_are_for_cufund_run_not_a_live_fleet():
    script = [[0.5, {"command": "arm"}], [1.0, {"command": "takeoff", "altitude": 1.0}]]
    cfg = fleet_config(2)
    cfg["planner"] = {"kind": "commander", "script": script}
    cfg["vehicles"][1]["planner"] = {"kind": "commander", "script": script}  # a vehicle's own planner too
    live = LiveFleet(cfg, start=False)
    assert all(v.commander.params.script == () for v in live.vehicles.values())
    scripted = LiveFleet(cfg, start=False, script=True)
    assert all(len(v.commander.params.script) == 2 for v in scripted.vehicles.values())


def test_a_live_vehicle_outlives_its_scenarios_mission():
    """A served vehicle's run does not end where ``cufund run``'s would (as a single live run's does not): one left
    out of the scenario's fleet mission still answers its operator."""
    live = LiveFleet("fleet_survey", ["mission.request=survey the field with uav1 and uav2 at 4 m"], speed=float("inf"))
    try:
        assert live.vehicle("uav1").wait_until(lambda t: t["armed"], 20.0)  # the mission has started
        ack = live.vehicle("uav3").submit({"command": "arm"}).result(timeout=5)
        assert ack.result == "accepted" and live.ended is None
    finally:
        live.stop()


def test_each_vehicles_controller_gains_are_its_parameters():
    """As on a single served vehicle, the controllers' gains are parameters (PX4's names), each vehicle's own."""
    with LiveFleet(fleet_config(2), speed=float("inf")) as live:
        uav1, uav2 = live.vehicle("uav1"), live.vehicle("uav2")
        before = uav1.submit({"command": "get_params"}).result(timeout=5).data["MC_ROLL_P"]
        ack = uav2.submit({"command": "set_param", "name": "MC_ROLL_P", "value": before + 1.0}).result(timeout=5)
        assert ack.result == "accepted", ack
        assert uav2.submit({"command": "get_params"}).result(timeout=5).data["MC_ROLL_P"] == before + 1.0
        assert uav1.submit({"command": "get_params"}).result(timeout=5).data["MC_ROLL_P"] == before


def test_a_crashed_vehicle_says_so_and_the_others_fly_on():
    """A vehicle whose own run ends (a crash) ends as a single live run does: an event, and commands answered as
    failed with the reason instead of waiting forever; the rest of the fleet goes on."""
    from cufund.simulator import RunStatus

    with LiveFleet(fleet_config(2), speed=float("inf")) as live:
        uav1, uav2 = live.vehicle("uav1"), live.vehicle("uav2")
        assert uav2.wait_until(lambda t: t.get("p_W") is not None, 10.0)
        live.pause()
        uav2.simulator.stop(RunStatus.CRASHED, "hit a tree")
        live.resume()
        assert uav2.wait_until(lambda t: t["ended"] is not None, 5.0)
        ack = uav2.submit({"command": "arm"}).result(timeout=5)
        assert ack.result == "failed" and "hit a tree" in ack.message
        assert uav2.events.since(0)[-1]["kind"] == "crash"
        assert uav1.submit({"command": "arm"}).result(timeout=5).result == "accepted"
        assert live.ended is None and uav1.telemetry()["ended"] is None


def test_a_paused_fleet_answers_each_vehicles_commands_and_takes_a_new_speed():
    """The fleet's pacing is PacedLoop's: paused, no vehicle advances, yet each one's commands are answered (its
    commander processes them at the paused instant); a new speed is every vehicle's."""
    with LiveFleet(fleet_config(2), speed=float("inf")) as live:
        uav1, uav2 = live.vehicle("uav1"), live.vehicle("uav2")
        assert uav1.wait_until(lambda t: t.get("p_W") is not None and t["t"] > 0.2, 10.0)
        live.pause()
        time.sleep(0.2)
        t_paused = live.t
        acks = live.submit_all({"command": "arm"})
        assert all(f.result(timeout=5).result == "accepted" for f in acks.values())
        assert live.t == t_paused and uav1.telemetry()["armed"] and uav2.telemetry()["armed"]
        live.set_speed(2.0)
        assert uav1.speed == uav2.speed == 2.0 and uav2.telemetry()["speed"] == 2.0
        live.resume()
        assert uav2.wait_until(lambda t: t["t"] > t_paused, 5.0)
