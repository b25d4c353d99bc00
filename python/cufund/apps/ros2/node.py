"""A minimal external ROS 2 node over Cyclone DDS, the lockstep contract's reference client (what the tests and the
benchmark run as "the external node", in its own process): ``python -m cufund.apps.ros2.node --domain 7 --name n``.

It subscribes to ``/clock``, ``/imu``, ``/tf``, ``/tf_static`` and the LiDAR topic, keeps what it received, answers
each ``/clock`` on ``/cufund/step_ack`` (after ``--sleep`` seconds per message received, to play a slow node), may
send a ``PoseStamped`` goal at a simulated time, and writes a JSON summary when the bridge falls silent. The same
loopback-only configuration as the bridge (:func:`cufund.apps.ros2.dds.cyclone_config`).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from typing import Any

from . import idl
from .config import ACK_TOPIC
from .dds import QOS, DdsParticipant, QosProfile

NS = 1_000_000_000


def _ns(stamp: Any) -> int:
    return int(stamp.sec) * NS + int(stamp.nanosec)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--domain", type=int, default=0)
    ap.add_argument("--name", default="cufund_test_node")
    ap.add_argument("--lidar", default="/livox/lidar")
    ap.add_argument("--sleep", type=float, default=0.0, help="seconds slept per message received")
    ap.add_argument("--goal", help="x,y,z,t: a PoseStamped goal on /goal_pose, sent when /clock reaches t")
    ap.add_argument("--no-ack", action="store_true", help="never answer (a node that does not play lockstep)")
    ap.add_argument("--idle-exit", type=float, default=5.0, help="exit after this long without a message [s]")
    ap.add_argument("--out", help="JSON summary file")
    ap.add_argument(
        "--estimator",
        help="IN:OUT: play an external estimator, answering each geometry_msgs/PoseStamped on IN with a "
        "nav_msgs/Odometry of that pose (zero twist) on OUT",
    )
    ap.add_argument(
        "--px4-offboard",
        help="x,y,z (NED, as px4_ros_com's offboard_control example): each /clock, an OffboardControlMode and a "
        "TrajectorySetpoint to that position; after 10 of them, VehicleCommand DO_SET_MODE offboard and ARM",
    )
    ap.add_argument("--camera", help="a camera's name: read /camera/NAME/image_raw (bytes) and camera_info")
    ap.add_argument("--raw", action="store_true", help="count the bytes of data topics without decoding them")
    ap.add_argument("--topics", help="comma-separated subset of /clock,/imu,/tf,/tf_static and the LiDAR to read")
    args = ap.parse_args(argv)

    dds = DdsParticipant(args.domain)
    readers = {
        "/clock": dds.reader("/clock", "rosgraph_msgs/msg/Clock", QosProfile(depth=1000)),
        "/imu": dds.reader("/imu", "sensor_msgs/msg/Imu", QosProfile(reliable=False, depth=1000)),
        "/tf": dds.reader("/tf", "tf2_msgs/msg/TFMessage", QosProfile(depth=1000)),
        "/tf_static": dds.reader("/tf_static", "tf2_msgs/msg/TFMessage", QOS["tf_static"]),
        args.lidar: dds.reader(args.lidar, "sensor_msgs/msg/PointCloud2", QosProfile(depth=1000)),
    }
    if args.topics:
        keep = set(args.topics.split(",")) | {"/clock"}
        readers = {k: v for k, v in readers.items() if k in keep}
    if args.camera:
        base = f"/camera/{args.camera}"
        readers[base + "/image_raw"] = dds.reader(
            base + "/image_raw", "sensor_msgs/msg/Image", QosProfile(False, depth=100)
        )
        readers[base + "/camera_info"] = dds.reader(
            base + "/camera_info", "sensor_msgs/msg/CameraInfo", QosProfile(False, depth=100)
        )
    odom_writer: Any = None
    pose_in = odom_out = ""
    if args.estimator:
        pose_in, odom_out = args.estimator.split(":")
        readers[pose_in] = dds.reader(pose_in, "geometry_msgs/msg/PoseStamped", QosProfile(depth=1000))
    ack = dds.topic(ACK_TOPIC, "std_msgs/msg/Header")
    from cyclonedds.pub import DataWriter

    ack_writer = DataWriter(dds.participant, ack, qos=QOS["ack"].qos())
    goal_writer = DataWriter(
        dds.participant, dds.topic("/goal_pose", "geometry_msgs/msg/PoseStamped"), qos=QOS["default"].qos()
    )
    goal = [float(v) for v in args.goal.split(",")] if args.goal else None
    px4: dict[str, Any] = {}
    if args.px4_offboard:
        for key, rtype in (
            ("mode", "px4_msgs/msg/OffboardControlMode"),
            ("setpoint", "px4_msgs/msg/TrajectorySetpoint"),
            ("command", "px4_msgs/msg/VehicleCommand"),
        ):
            name = {"mode": "offboard_control_mode", "setpoint": "trajectory_setpoint", "command": "vehicle_command"}
            px4[key] = DataWriter(dds.participant, dds.topic(f"/fmu/in/{name[key]}", rtype), qos=QOS["default"].qos())
        px4_target = [float(v) for v in args.px4_offboard.split(",")]
        px4_count = 0
    if args.estimator:
        odom_writer = DataWriter(
            dds.participant, dds.topic(odom_out, "nav_msgs/msg/Odometry"), qos=QOS["default"].qos()
        )
    # announce once the bridge's publishers have matched (so nothing it publishes is missed)
    t0 = time.monotonic()
    while time.monotonic() - t0 < 30:
        if all(len(r.get_matched_publications()) > 0 for k, r in readers.items() if k != "/tf_static") and len(
            ack_writer.get_matched_subscriptions()
        ):
            break
        time.sleep(0.01)
    if not args.no_ack:
        ack_writer.write(idl.Header(idl.Time(-1, 0), args.name))
    got: dict[str, list[Any]] = {k: [] for k in readers}
    types: dict[str, str] = {}
    last = time.monotonic()
    goal_sent = False
    from cyclonedds._clayer import ddspy_take
    from cyclonedds.core import InstanceState, ReadCondition, SampleState, ViewState, WaitSet
    from cyclonedds.util import duration

    waitset = WaitSet(dds.participant)  # woken by /clock, written after the step's data: one wake-up a step
    waitset.attach(ReadCondition(readers["/clock"], SampleState.NotRead))
    order = [k for k in readers if k != "/clock"] + ["/clock"]  # the step's data first, its /clock (answered) last
    any_state = SampleState.Any | ViewState.Any | InstanceState.Any
    while time.monotonic() - last < args.idle_exit:
        progressed = False
        for topic in order:
            r = readers[topic]
            if (args.raw and topic not in ("/clock", "/tf_static")) or topic.endswith("/image_raw"):  # bytes only
                raw = ddspy_take(r._ref, any_state, 1000)
                for data, info in raw:
                    if info.valid_data:
                        progressed = True
                        got[topic].append(len(data))
                continue
            for s in r.take(N=1000):
                if not s.sample_info.valid_data:
                    continue
                progressed = True
                types[topic] = type(s).__idl_typename__ if hasattr(type(s), "__idl_typename__") else type(s).__name__
                if args.sleep:
                    time.sleep(args.sleep)
                if topic == "/clock":
                    t_ns = _ns(s.clock)
                    got[topic].append(t_ns)
                    if goal is not None and not goal_sent and t_ns >= goal[3] * NS:
                        goal_writer.write(
                            idl.PoseStamped(
                                idl.Header(s.clock, "world"), idl.Pose(idl.Point(*goal[:3]), idl.Quaternion())
                            )
                        )
                        goal_sent = True
                    if px4:
                        us = t_ns // 1000
                        px4["mode"].write(idl.OffboardControlMode(timestamp=us, position=True))
                        px4["setpoint"].write(idl.TrajectorySetpoint(timestamp=us, position=px4_target, yaw=-3.14))  # type: ignore[arg-type]
                        px4_count += 1
                        if px4_count == 10:
                            px4["command"].write(idl.VehicleCommand(us, param1=1.0, param2=6.0, command=176))
                            px4["command"].write(idl.VehicleCommand(us, param1=1.0, command=400))
                    if not args.no_ack:
                        ack_writer.write(idl.Header(s.clock, args.name))
                elif topic == "/imu":
                    got[topic].append(
                        [
                            _ns(s.header.stamp),
                            s.header.frame_id,
                            *(getattr(s.angular_velocity, a) for a in "xyz"),
                            *(getattr(s.linear_acceleration, a) for a in "xyz"),
                        ]
                    )
                elif topic.endswith("/camera_info"):
                    got[topic].append([_ns(s.header.stamp), s.header.frame_id, s.width, s.height, list(s.k), list(s.d)])
                elif args.estimator and topic == pose_in:
                    got[topic].append([_ns(s.header.stamp)])
                    odom = idl.Odometry(
                        s.header, "base_link", idl.PoseWithCovariance(s.pose), idl.TwistWithCovariance()
                    )
                    odom_writer.write(odom)
                elif topic in ("/tf", "/tf_static"):
                    for tr in s.transforms:
                        v, q = tr.transform.translation, tr.transform.rotation
                        got[topic].append(
                            [
                                _ns(tr.header.stamp),
                                tr.header.frame_id,
                                tr.child_frame_id,
                                v.x,
                                v.y,
                                v.z,
                                q.x,
                                q.y,
                                q.z,
                                q.w,
                            ]
                        )
                else:
                    got[topic].append(
                        [
                            _ns(s.header.stamp),
                            s.header.frame_id,
                            s.width,
                            s.point_step,
                            [f.name for f in s.fields],
                            len(s.data),
                        ]
                    )
        if progressed:
            last = time.monotonic()
        else:
            waitset.wait(duration(milliseconds=100))
    summary = {"name": args.name, "received": got, "types": types}
    if args.out:
        with open(args.out, "w") as f:
            json.dump(summary, f)
    dds.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
