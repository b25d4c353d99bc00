"""Fleets in one world: far apart, each vehicle's run is its single-vehicle run bit for bit; a head-on pair without
deconfliction collides (CRASHED, naming both); the ``vehicles:`` key's errors name the field."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cufund.core.config import ConfigError
from cufund.scenarios.build import build_simulation, run_scenario
from cufund.scenarios.fleet import build_fleet, vehicle_scenario, vehicle_seed
from cufund.scenarios.run_folder import run_into_folder
from cufund.scenarios.schema import ScenarioConfig, load_scenario

TIMING = ("wall_time_s", "real_time_factor", "component_seconds")


def _fleet(vehicles, **extra):
    data = load_scenario("square").to_dict()
    data.update(name="fleet_test", vehicles=vehicles, **extra)
    return ScenarioConfig.from_dict(data)


def _square_at(name, x, y):
    wp = [[x, y, 1.5], [x + 1, y, 1.5], [x + 1, y + 1, 1.5], [x, y + 1, 1.5], [x, y, 1.5]]
    return {"name": name, "start": {"p": [x, y, 0.0]}, "trajectory": {"waypoints": wp}}


def _untimed(m):
    return {k: v for k, v in m.items() if k not in TIMING}


def test_far_apart_each_vehicle_is_its_single_run_bit_for_bit():
    cfg = _fleet([_square_at("uav1", 0, 0), _square_at("uav2", 40, 0), _square_at("uav3", 0, 40)], downwash=True)
    run = build_fleet(cfg).run()
    assert run.status == "completed" and run.metrics["fleet_collisions"] == 0
    assert run.metrics["fleet_min_separation_m"] == pytest.approx(40.0)
    for name in ("uav1", "uav2", "uav3"):
        alone = run_scenario(vehicle_scenario(cfg, name))
        assert alone.config.seed == vehicle_seed(cfg.seed, name)
        a, b = alone.result.states, run.runs[name].result.states
        assert set(a) == set(b)
        for k in a:
            assert np.array_equal(a[k], b[k]), (name, k)
        assert _untimed(alone.metrics) == _untimed(run.metrics["vehicles"][name])
    # the seeds differ per vehicle and do not depend on the other vehicles
    assert len({vehicle_seed(0, n) for n in ("uav1", "uav2", "uav3")}) == 3
    two = _fleet([_square_at("uav2", 40, 0)])
    assert vehicle_scenario(two, "uav2").seed == vehicle_scenario(cfg, "uav2").seed


def test_noisy_sensors_far_apart_bit_for_bit():
    """With sensor noise and an estimator's inputs the per-vehicle streams are the single run's."""
    base = load_scenario("square_sensors").to_dict()
    base.update(name="fleet_sensors", duration=6.0)
    base["vehicles"] = [{"name": "a", "start": {"p": [0, 0, 0]}}, _square_at("b", 30, 0)]
    cfg = ScenarioConfig.from_dict(base)
    run = build_fleet(cfg).run()
    for name in ("a", "b"):
        alone = run_scenario(vehicle_scenario(cfg, name))
        for k, v in alone.result.states.items():
            assert np.array_equal(v, run.runs[name].result.states[k]), (name, k)
        assert _untimed(alone.metrics) == _untimed(run.metrics["vehicles"][name])
    # and the two vehicles' noise differs (their own streams, not one shared)
    ta, tb = (run.runs[n].result.topics for n in ("a", "b"))
    common = sorted(set(ta) & set(tb))
    assert common and any(
        not np.array_equal(np.asarray(ta[t][f]), np.asarray(tb[t][f])) for t in common for f in ta[t] if f != "t"
    )


def test_head_on_pair_collides():
    a = {"name": "east", "start": {"p": [0, 0, 0]}, "trajectory": {"waypoints": [[0, 0, 1.5], [6, 0, 1.5]]}}
    b = {"name": "west", "start": {"p": [6, 0, 0]}, "trajectory": {"waypoints": [[6, 0, 1.5], [0, 0, 1.5]]}}
    run = build_fleet(_fleet([a, b], duration=20.0)).run()
    assert run.metrics["fleet_collisions"] >= 1
    assert run.status == "crashed"
    assert "east" in run.message and "west" in run.message
    for name, other in (("east", "west"), ("west", "east")):
        m = run.metrics["vehicles"][name]
        assert m["status"] == "crashed" and other in m["message"]
    event = run.metrics["fleet_collision_events"][0]
    assert set(event["vehicles"]) == {"east", "west"} and 2.0 < event["point_W"][0] < 4.0
    assert run.metrics["fleet_min_separation_m"] < 0.3


def test_fleet_square_scenario(tmp_path):
    """The built-in fleet_square completes and each vehicle tracks as well as the single-vehicle square."""
    single = run_scenario(load_scenario("square")).metrics["tracking_rmse_m"]
    run = run_into_folder(load_scenario("fleet_square"), tmp_path, plots=False, replay=False)
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert run.status == "completed" and m["status"] == "completed"
    assert set(m["vehicles"]) == {"uav1", "uav2", "uav3"} and m["fleet_collisions"] == 0
    assert m["fleet_min_separation_m"] == pytest.approx(3.0, abs=0.05)
    for vm in m["vehicles"].values():
        assert vm["status"] == "completed"
        assert vm["tracking_rmse_m"] <= single * 1.05
    from mcap.reader import make_reader

    with open(tmp_path / "run.mcap", "rb") as f:  # every channel, read without cufund's code
        topics = {c.topic for c in make_reader(f).get_summary().channels.values()}
    for name in ("uav1", "uav2", "uav3"):
        assert {f"/{name}/actuator/command", f"/{name}/truth/odometry"} <= topics
    assert not any(t.startswith(("/control", "/truth", "/sensors")) for t in topics)
    assert {"/clock", "/tf_static", "/uav1/planner/path", "/uav3/planner/path"} <= topics


def test_vehicle_access_for_a_driver():
    fleet = build_fleet(load_scenario("fleet_square"))
    assert fleet.names == ("uav1", "uav2", "uav3")
    v = fleet.vehicle("uav2")
    assert v.simulator is v.built.simulator and v.bus is None  # before the run starts
    assert v.topic("/sensors/imu") == "/uav2/sensors/imu"
    assert fleet.advance_to(0.5)
    assert v.bus is v.simulator.bus
    assert fleet.t == pytest.approx(0.5) and v.simulator.t == pytest.approx(0.5)
    with pytest.raises(KeyError, match="uav9"):
        fleet.vehicle("uav9")


@pytest.mark.parametrize(
    "vehicles, match",
    [
        ("uav1", "vehicles must be a list"),
        ([], "at least one vehicle"),
        ([{"start": {"p": [0, 0, 0]}}], r"vehicles\[0\].name"),
        ([{"name": "a"}, {"name": "a"}], "two vehicles are named 'a'"),
        ([{"name": "a", "start": {"p": [0, 0]}}], "vehicles.a.start.p must be 3 numbers"),
        ([{"name": "a", "start": {"yaw": 90}}], "radians, not degrees"),
        ([{"name": "a", "world": "forest"}], "unknown key 'world' in vehicles.a"),
        ([{"name": "a", "controller": "nosuch"}], "vehicles.a"),
    ],
)
def test_bad_vehicles_named(vehicles, match):
    with pytest.raises(ConfigError, match=match):
        cfg = _fleet(vehicles)
        build_fleet(cfg)


def test_start_yaw_is_checked_as_a_vehicles_is():
    """The scenario's start_yaw and a vehicle's start.yaw take the same headings, [-2 pi, 2 pi] [rad]."""
    data = load_scenario("square").to_dict()
    assert ScenarioConfig.from_dict({**data, "start_yaw": -2 * np.pi}).start_yaw == -2 * np.pi
    with pytest.raises(ConfigError, match="start_yaw must be a heading in"):
        ScenarioConfig.from_dict({**data, "start_yaw": 6.5})
    with pytest.raises(ConfigError, match="radians, not degrees"):
        _fleet([{"name": "a", "start": {"yaw": 6.5}}])


def test_single_vehicle_build_refuses_a_fleet():
    with pytest.raises(ConfigError, match="build_fleet"):
        build_simulation(load_scenario("fleet_square"))
    assert "vehicles" not in load_scenario("square").to_dict()  # a single vehicle's config.yaml as before


def test_until_done_false_keeps_landed_vehicles_running():
    """Flown from outside (MAVLink), a vehicle's run does not end when it has landed after its reference."""
    cfg = _fleet([_square_at("a", 0, 0), _square_at("b", 5, 0)], duration=18.0)
    ends = build_fleet(cfg)
    assert not ends.advance_to(17.0)  # both landed (~15.5 s): the fleet's run is over
    assert ends.simulator.status is not None and ends.simulator.status.value == "completed"
    goes_on = build_fleet(cfg, until_done=False)
    assert goes_on.advance_to(17.0) and goes_on.t == pytest.approx(17.0)
    assert all(goes_on.vehicle(n).simulator.status is None for n in goes_on.names)


def test_fleet_log_frames_are_each_vehicles_own(tmp_path):
    """In a fleet's log each vehicle's sensor and body frames are under its name (uav1/imu, uav2/imu), and every frame
    a message names resolves to world through /tf and /tf_static."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    base = load_scenario("square_sensors").to_dict()
    base.update(name="fleet_frames", duration=1.0)
    base["vehicles"] = [{"name": "uav1", "start": {"p": [0, 0, 0]}}, _square_at("uav2", 5, 0)]
    run_into_folder(ScenarioConfig.from_dict(base), tmp_path, plots=False, replay=False)
    parents: dict[str, str] = {}
    named: dict[str, set[str]] = {}
    factory = DecoderFactory()
    with open(tmp_path / "run.mcap", "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            if channel.message_encoding != "cdr":
                continue
            msg = factory.decoder_for("cdr", schema)(message.data)
            for tf in getattr(msg, "transforms", ()):
                assert parents.setdefault(tf.child_frame_id, tf.header.frame_id) == tf.header.frame_id
            header = getattr(msg, "header", None)
            frames = named.setdefault(channel.topic, set())
            if header is not None:
                frames.add(header.frame_id)
            if getattr(msg, "child_frame_id", ""):
                frames.add(msg.child_frame_id)
    assert named["/uav1/sensors/imu/ros"] == {"uav1/imu"} and named["/uav2/sensors/imu/ros"] == {"uav2/imu"}
    assert named["/uav2/truth/odometry/ros"] == {"world", "uav2/base_link_truth"}
    for frame in set().union(*named.values()):
        seen = set()
        while frame != "world":
            assert frame in parents and frame not in seen, f"frame {frame} does not resolve to world ({parents})"
            seen.add(frame)
            frame = parents[frame]


def test_a_fleet_stopped_by_a_signal_come_back_as_another_exception_finishes_its_folder(tmp_path):
    """As a single run's (tests/security/test_killed_run.py): the signal the handler recorded makes the fleet's run
    interrupted even when its exception reached the run as another type (metrics.json, RunInterrupted raised)."""
    import signal

    from cufund.core.components import Component
    from cufund.scenarios.build import RunInterrupted
    from cufund.scenarios.run_folder import run_fleet_into_folder

    class Converting(Component):
        name = "converting"
        rate_hz = 10.0

        def step(self, t, bus):
            if t >= 0.5:
                try:
                    RunInterrupted.raise_for(signal.SIGTERM)
                except RunInterrupted:
                    raise RuntimeError("an error a compiled layer made of it") from None

    fleet = build_fleet(_fleet([_square_at("a", 0, 0), _square_at("b", 5, 0)], duration=5.0))
    fleet.vehicle("b").simulator.add(Converting())
    try:
        with pytest.raises(RunInterrupted) as stop:
            run_fleet_into_folder(fleet, tmp_path, plots=False, replay=False)
    finally:
        RunInterrupted.received = None
    assert stop.value.signum == signal.SIGTERM and isinstance(stop.value.__cause__, RuntimeError)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics == {"status": "interrupted", "message": "stopped by SIGTERM", "sim_time_s": metrics["sim_time_s"]}
    assert 0.4 <= metrics["sim_time_s"] < 1.0
