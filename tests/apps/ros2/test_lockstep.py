"""Lockstep: simulated time waits for the nodes. A slow node (50 ms per message) still receives every IMU sample,
and a run whose vehicle it commands is bit-identical to one with a fast node; a node that never answers ends the
run with an error naming it after the timeout."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("cyclonedds")

from test_bridge import domain, finish, scenario, start_node

from cufund.apps.ros2.bridge import Ros2Timeout
from cufund.scenarios.build import run_scenario


def _run(tmp_path, d: int, sleep: float):
    node, out = start_node(
        tmp_path, d, f"n{int(sleep * 1000)}", "--goal=-2,0.5,1.0,0.2", "--topics", "/clock,/imu", "--sleep", str(sleep)
    )
    cfg = scenario(
        "vehicle",
        {"domain_id": d, "lockstep_nodes": [f"n{int(sleep * 1000)}"], "rate_hz": 50.0, "timeout_s": 30},
        duration=1.0,
        planner={"kind": "commander", "takeoff_altitude": 1.0},
        sensors={
            "imu": {"kind": "icm42688p", "rate_hz": 100.0},
            "pose": {"kind": "pose", "rate_hz": 10.0, "position_sigma_m": 0.001, "attitude_sigma_rad": 0.001},
        },
    )
    return run_scenario(cfg), finish(node, out)


def test_a_slow_node_sees_every_imu_sample_and_the_run_is_bit_identical(tmp_path):
    d = domain(3)
    fast, fast_got = _run(tmp_path, d, 0.0)
    slow, slow_got = _run(tmp_path, d, 0.05)
    last_clock = fast_got["received"]["/clock"][-1] / 1e9  # samples after the bridge's last step are not sent
    assert slow_got["received"]["/clock"] == fast_got["received"]["/clock"]
    n_imu = int(np.count_nonzero(np.asarray(fast.result.topics["/sensors/imu"]["t"]) <= last_clock + 1e-9))
    assert n_imu >= 90
    assert len(fast_got["received"]["/imu"]) == len(slow_got["received"]["/imu"]) == n_imu
    assert fast_got["received"]["/imu"] == slow_got["received"]["/imu"]
    for key in ("t", "p_W", "v_W", "q_WB"):
        assert np.array_equal(fast.result.states[key], slow.result.states[key]), key
    est_f, est_s = fast.result.topics["/estimator/odometry"], slow.result.topics["/estimator/odometry"]
    assert np.array_equal(np.asarray(est_f["p_W"]), np.asarray(est_s["p_W"]))
    # the node's goal did act: the vehicle was armed and left the pad's attitude command
    assert np.max(fast.result.states["p_W"][:, 2]) > 0.01


def test_a_node_that_never_answers_is_an_error_naming_it(tmp_path):
    d = domain(4)
    node, out = start_node(tmp_path, d, "mute", "--no-ack", "--topics", "/clock")
    cfg = scenario("vehicle", {"domain_id": d, "lockstep_nodes": ["mute"], "timeout_s": 1.0}, duration=1.0)
    with pytest.raises(Ros2Timeout, match="mute"):
        run_scenario(cfg)
    node.kill()
    node.wait()


def test_a_second_run_of_the_same_simulation_keeps_the_node(tmp_path):
    # the participant stays open across runs: the node, which announced itself once, answers the second run too
    from cufund.scenarios.build import build_simulation

    d = domain(11)
    node, out = start_node(tmp_path, d, "twice", "--topics", "/clock")
    cfg = scenario(
        "vehicle", {"domain_id": d, "lockstep_nodes": ["twice"], "rate_hz": 50.0, "timeout_s": 20}, duration=0.4
    )
    sim = build_simulation(cfg).simulator
    sim.run(0.4)
    sim.run(0.4)
    clocks = finish(node, out)["received"]["/clock"]
    assert len(clocks) >= 40 and len(set(clocks)) >= 20
