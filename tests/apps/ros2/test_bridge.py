"""The ROS 2 bridge against an external node: a Cyclone DDS participant in its own process
(:mod:`cufund.apps.ros2.node`) that decodes what it receives with its own IDL structs (not cufund's CDR encoder)
receives /clock, /imu, /tf, /tf_static and the LiDAR with ROS 2's type names and the run's values, and its
PoseStamped goal flies the vehicle there."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("cyclonedds")

from cufund.scenarios.build import run_scenario
from cufund.scenarios.schema import ScenarioConfig, load_scenario

NS = 1_000_000_000


def domain(offset: int) -> int:
    return 1 + (os.getpid() * 7 + offset) % 140


def start_node(tmp_path, d: int, name: str, *extra: str) -> tuple[subprocess.Popen, str]:
    out = str(tmp_path / f"{name}.json")
    cmd = [sys.executable, "-m", "cufund.apps.ros2.node", "--domain", str(d), "--name", name, "--out", out]
    return subprocess.Popen([*cmd, "--idle-exit", "3", *extra]), out


def scenario(name: str, ros2: dict, **changes) -> ScenarioConfig:
    cfg = load_scenario(name)
    data = cfg.to_dict()
    data.update(changes)
    data["ros2"] = ros2
    return ScenarioConfig.from_dict(data, cfg.base_dir)


def finish(node: subprocess.Popen, out: str) -> dict:
    assert node.wait(timeout=60) == 0
    with open(out) as f:
        return json.load(f)


def test_the_node_receives_the_sensors_with_ros2_types_and_values(tmp_path):
    d = domain(1)
    node, out = start_node(tmp_path, d, "listener")
    cfg = scenario("square_lio", {"domain_id": d, "lockstep_nodes": ["listener"], "timeout_s": 30}, duration=0.4)
    run = run_scenario(cfg)
    got = finish(node, out)
    assert got["types"] == {
        "/clock": "rosgraph_msgs::msg::dds_::Clock_",
        "/imu": "sensor_msgs::msg::dds_::Imu_",
        "/tf": "tf2_msgs::msg::dds_::TFMessage_",
        "/tf_static": "tf2_msgs::msg::dds_::TFMessage_",
        "/livox/lidar": "sensor_msgs::msg::dds_::PointCloud2_",
    }
    rec = got["received"]
    imu = run.result.topics["/sensors/imu"]
    assert len(rec["/imu"]) == len(imu["t"]) > 50  # every sample (lockstep)
    stamps = np.array([r[0] for r in rec["/imu"]])
    np.testing.assert_array_equal(stamps, np.round(np.asarray(imu["t"]) * NS).astype(np.int64))
    assert {r[1] for r in rec["/imu"]} == {"imu"}
    np.testing.assert_array_equal(np.array([r[2:5] for r in rec["/imu"]]), np.asarray(imu["w_I"]))
    np.testing.assert_array_equal(np.array([r[5:8] for r in rec["/imu"]]), np.asarray(imu["f_I"]))
    # /clock: one per bridge step (the IMU's rate), increasing
    clock = np.array(rec["/clock"])
    assert len(clock) >= len(stamps) and np.all(np.diff(clock) > 0)
    # /tf_static: the LiDAR's mounting from the scenario, odom under world
    static = {(r[1], r[2]): r[3:] for r in rec["/tf_static"]}
    lidar = cfg.sensors["lidar"].extrinsic
    w, x, y, z = lidar.q
    np.testing.assert_allclose(static[("base_link", "lidar")], [*lidar.t, x, y, z, w])
    assert ("world", "odom") in static
    # /tf: the truth under world and the estimate under odom, each at the truth's / the estimate's stamps
    children = {(r[1], r[2]) for r in rec["/tf"]}
    estimated = len(run.result.topics.get("/estimator/odometry", {}).get("t", [])) > 0
    assert children == {("world", "base_link_truth"), *([("odom", "base_link")] if estimated else [])}
    # the LiDAR: livox_ros_driver2's point layout, its frames' sizes
    clouds = rec["/livox/lidar"]
    assert clouds and all(c[1] == "lidar" for c in clouds)
    assert clouds[0][4] == ["x", "y", "z", "intensity", "tag", "line", "timestamp"] and clouds[0][3] == 26
    assert all(c[5] == c[2] * 26 for c in clouds)


def test_a_pose_goal_from_the_node_flies_the_vehicle_there(tmp_path):
    d = domain(2)
    goal = (-1.0, 1.0, 1.2)
    node, out = start_node(tmp_path, d, "planner", f"--goal={goal[0]},{goal[1]},{goal[2]},0.5", "--topics", "/clock")
    cfg = scenario(
        "vehicle",
        {"domain_id": d, "lockstep_nodes": ["planner"], "rate_hz": 50.0, "timeout_s": 30},
        duration=12.0,
        planner={"kind": "commander", "takeoff_altitude": 1.2},
    )
    run = run_scenario(cfg)
    finish(node, out)
    p = run.result.states["p_W"]
    start = np.asarray(cfg.start_p_W)
    assert np.linalg.norm(p[0] - start) < 0.05
    assert np.linalg.norm(p[-1] - np.asarray(goal)) < 0.2, f"ended at {p[-1]}, goal {goal}"


def test_a_px4_offboard_node_arms_and_flies_the_vehicle(tmp_path):
    # px4_ros_com's offboard_control flow: heartbeat + NED setpoint every step, after 10: DO_SET_MODE offboard, ARM
    d = domain(8)
    ned = (0.5, -2.0, -1.5)
    node, out = start_node(tmp_path, d, "px4", f"--px4-offboard={ned[0]},{ned[1]},{ned[2]}", "--topics", "/clock")
    cfg = scenario(
        "vehicle",
        {"domain_id": d, "lockstep_nodes": ["px4"], "rate_hz": 50.0, "timeout_s": 30},
        duration=8.0,
        planner={"kind": "commander"},
    )
    run = run_scenario(cfg)
    finish(node, out)
    p = run.result.states["p_W"]
    enu = np.array([ned[1], ned[0], -ned[2]])  # NED -> ENU
    assert np.linalg.norm(p[-1] - enu) < 0.2, f"ended at {p[-1]}, target {enu}"
    q = run.result.states["q_WB"][-1]
    yaw_enu = np.arctan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] ** 2 + q[3] ** 2))
    expected = np.pi / 2 + 3.14  # ENU yaw = pi/2 - NED yaw
    assert abs(np.angle(np.exp(1j * (yaw_enu - expected)))) < 0.1


def test_a_depth_camera_is_image_raw_and_its_camera_info(tmp_path):
    from cufund.sensors.camera import d435_depth

    d = domain(9)
    node, out = start_node(tmp_path, d, "viewer", "--topics", "/clock", "--camera", "depth")
    cfg = load_scenario("square_lio")
    data = cfg.to_dict()
    data.update(duration=0.35, estimator=None)
    data["sensors"]["depth"] = {"kind": "d435_depth", "rate_hz": 10.0}
    data["ros2"] = {"domain_id": d, "lockstep_nodes": ["viewer"], "timeout_s": 30}
    run = run_scenario(ScenarioConfig.from_dict(data, cfg.base_dir))
    got = finish(node, out)["received"]
    k = d435_depth()
    frames = run.result.topics.get("/sensors/depth", {}).get("t", [])
    images, infos = got["/camera/depth/image_raw"], got["/camera/depth/camera_info"]
    assert len(images) == len(infos) >= 3
    assert all(n >= k.width * k.height * 4 for n in images)  # 32FC1
    stamp, frame, width, height, kk, dist = infos[0]
    assert (frame, width, height) == ("depth", k.width, k.height)
    assert kk == [k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0] and dist == [0.0] * 5
    if len(frames):
        assert stamp == round(frames[0] * NS)


def test_any_cufund_topic_with_a_ros2_message_can_be_mapped(tmp_path):
    # the motion-capture pose is no default topic; the scenario maps it, the node receives every pose
    d = domain(12)
    node, out = start_node(tmp_path, d, "mocap", "--topics", "/clock", "--estimator", "/mocap/pose:/unused")
    ros2 = {"domain_id": d, "lockstep_nodes": ["mocap"], "rate_hz": 50.0, "topics": {"/sensors/pose": "/mocap/pose"}}
    run = run_scenario(scenario("vehicle", ros2, duration=1.0))
    got = finish(node, out)["received"]["/mocap/pose"]
    poses = np.asarray(run.result.topics["/sensors/pose"]["t"])
    stamps = np.array([g[0] for g in got])
    np.testing.assert_array_equal(stamps, np.round(poses[: len(stamps)] * NS).astype(np.int64))
    assert len(stamps) >= len(poses) - 1 >= 8  # all but one sent after the last step


def test_a_topic_nobody_reads_is_not_encoded():
    # without a matched reader a volatile sample reaches no one: the bridge does not serialise it (a LiDAR cloud or
    # an image each frame, the truth and /tf each step); once a reader has matched, every sample is encoded
    from cufund.apps.ros2.dds import DdsParticipant, QosProfile
    from cufund.scenarios.build import build_simulation

    d = domain(13)
    cfg = scenario("vehicle", {"domain_id": d, "lockstep": False, "rate_hz": 50.0}, duration=0.3)
    sim = build_simulation(cfg).simulator
    bridge = next(c for c in sim.components if type(c).__name__ == "Ros2Bridge")
    encoded: dict[str, int] = {}

    def counting(o):
        def encode(m):
            encoded[o.topic] = encoded.get(o.topic, 0) + 1
            return inner(m)

        inner = o.encode
        return encode

    for o in bridge.outs:
        o.encode = counting(o)
    sim.run(0.3)
    assert encoded == {} and bridge.stats["messages"] == 0 and bridge.stats["steps"] >= 10
    peer = DdsParticipant(d)  # in this process: matched as soon as the bridge's writer exists
    try:
        reader = peer.reader("/imu", "sensor_msgs/msg/Imu", QosProfile(reliable=False, depth=1000))
        sim.run(0.3)
        got = [s for s in reader.take(N=1000) if s.sample_info.valid_data]
    finally:
        peer.close()
    assert set(encoded) == {"/sensors/imu"} and len(got) == encoded["/sensors/imu"] == bridge.stats["messages"] > 10
