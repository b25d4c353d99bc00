"""How the bridge maps ROS 2 setpoint messages onto the commander (no DDS: the decoded structs are handed to it as
the readers would): a Path is a mission through its poses, a MultiDOFJointTrajectory offboard setpoints at each
point's time, a PositionCommand an offboard setpoint with its velocity, PX4's NED setpoints ENU ones only in
offboard mode with a fresh heartbeat. Headings against scipy's rotations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

pytest.importorskip("cyclonedds")

from cufund.apps.ros2 import idl
from cufund.apps.ros2.bridge import Ros2Bridge
from cufund.apps.ros2.config import Ros2Params
from cufund.missions.commands import parse_command

NS = 1_000_000_000


class FakeCommander:
    def __init__(self, landed: bool = False) -> None:
        self.landed = landed
        self.submitted: list[dict] = []

    def submit(self, cmd: dict) -> None:
        parse_command(cmd)  # what the commander accepts
        self.submitted.append(cmd)


def bridge(landed: bool = False) -> tuple[Ros2Bridge, FakeCommander]:
    c = FakeCommander(landed)
    b = Ros2Bridge(Ros2Params(), [], [], c, 50.0)
    b._scheduled, b._offboard_mode_ns, b._offboard_wanted, b._readers = [], None, False, {}
    return b, c


def quat(yaw: float) -> idl.Quaternion:
    x, y, z, w = Rotation.from_euler("z", yaw).as_quat()
    return idl.Quaternion(x, y, z, w)


def test_a_path_is_a_mission_through_its_poses():
    b, c = bridge(landed=True)
    poses = [(1.0, 2.0, 1.5, 0.3), (3.0, -1.0, 2.0, -2.0)]
    msg = idl.Path(
        idl.Header(),
        [idl.PoseStamped(idl.Header(), idl.Pose(idl.Point(x, y, z), quat(yaw))) for x, y, z, yaw in poses],
    )
    b._on_path(msg, 0)
    assert [m["command"] for m in c.submitted] == ["arm", "mission_upload", "mission_start"]
    items = c.submitted[1]["items"]
    for item, (x, y, z, yaw) in zip(items, poses, strict=True):
        assert item["p_W"] == [x, y, z]
        assert math.isclose(item["yaw"], yaw, abs_tol=1e-12)


def test_a_multidof_trajectory_is_offboard_setpoints_at_each_point_s_time():
    b, c = bridge()
    points = [
        idl.MultiDOFJointTrajectoryPoint(
            [idl.Transform(idl.Vector3(0.0, 0.0, k + 1.0), quat(0.1 * k))],
            [idl.Twist(idl.Vector3(0.5, 0.0, 0.0))],
            [],
            idl.Duration(k, 0),
        )
        for k in range(3)
    ]
    msg = idl.MultiDOFJointTrajectory(idl.Header(idl.Time(2, 0)), ["base_link"], points)
    b._on_trajectory(msg, 2 * NS)
    assert len(c.submitted) == 1 and c.submitted[0]["p_W"] == [0.0, 0.0, 1.0]  # time_from_start 0: now
    b._take_commands(3 * NS - 1)
    assert len(c.submitted) == 1
    b._take_commands(3 * NS)
    assert c.submitted[1]["p_W"] == [0.0, 0.0, 2.0] and c.submitted[1]["v_W"] == [0.5, 0.0, 0.0]
    assert math.isclose(c.submitted[1]["yaw"], 0.1, abs_tol=1e-12)


def test_a_position_command_is_an_offboard_setpoint_with_its_velocity():
    b, c = bridge()
    msg = idl.PositionCommand(
        idl.Header(), idl.Point(1.0, 2.0, 3.0), idl.Vector3(0.1, 0.2, 0.3), idl.Vector3(), idl.Vector3(), 0.7
    )
    b._on_position_command(msg, 0)
    assert c.submitted == [{"command": "offboard_position", "p_W": [1.0, 2.0, 3.0], "v_W": [0.1, 0.2, 0.3], "yaw": 0.7}]


def test_px4_setpoints_count_only_in_offboard_mode_with_a_fresh_heartbeat_and_turn_ned_into_enu():
    b, c = bridge()
    sp = idl.TrajectorySetpoint(position=[1.0, 2.0, -3.0], velocity=[0.1, 0.2, -0.3], yaw=0.4)
    b._on_px4_trajectory_setpoint(sp, 0)
    assert c.submitted == []  # not in offboard mode
    b._on_px4_vehicle_command(idl.VehicleCommand(param1=1.0, param2=6.0, command=176), 0)
    b._on_px4_trajectory_setpoint(sp, 0)
    assert c.submitted == []  # no heartbeat yet
    b._on_px4_offboard_control_mode(idl.OffboardControlMode(position=True), 1 * NS)
    b._on_px4_trajectory_setpoint(sp, int(1.5 * NS))
    cmd = c.submitted[-1]
    np.testing.assert_allclose(cmd["p_W"], [2.0, 1.0, 3.0])
    np.testing.assert_allclose(cmd["v_W"], [0.2, 0.1, 0.3], rtol=1e-6)
    # the heading: NED yaw 0.4 about down is ENU yaw pi/2 - 0.4 about up (the same direction on the ground)
    ned_heading = np.array([math.cos(0.4), math.sin(0.4)])  # (north, east)
    enu_heading = np.array([math.cos(cmd["yaw"]), math.sin(cmd["yaw"])])  # (east, north)
    np.testing.assert_allclose(enu_heading, ned_heading[::-1], atol=1e-6)
    n = len(c.submitted)
    b._on_px4_trajectory_setpoint(sp, int(1.6 * NS))  # 0.6 s after the heartbeat: PX4's COM_OF_LOSS_T (0.5 s)
    assert len(c.submitted) == n
    b._on_px4_vehicle_command(idl.VehicleCommand(param1=1.0, command=400), 0)
    assert c.submitted[-1] == {"command": "arm"}
