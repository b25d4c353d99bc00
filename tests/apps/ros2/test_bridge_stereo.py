"""A ``stereo_camera`` rig over the ROS 2 bridge, as ROS 2 stereo drivers publish one: a Cyclone DDS node in its
own process (this file run as a script, decoding with its own IDL structs, not cufund's CDR encoder) receives
``/stereo/left/image_raw`` and ``/stereo/right/image_raw`` with identical stamps, the very pixels the rig rendered,
in the cameras' optical frames, and ``camera_info`` whose P projects a known point where ``cv2.projectPoints``
does with the rig's calibration; ``/tf_static`` puts each optical frame where the rig's calibration says."""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("cyclonedds")

NS = 1_000_000_000
SIDES = ("left", "right")


def _ns(stamp) -> int:
    return int(stamp.sec) * NS + int(stamp.nanosec)


def node(argv: list[str] | None = None) -> int:
    """The external node: reads the stereo topics and /tf_static, answers each /clock on the lockstep topic."""
    from cyclonedds.core import ReadCondition, SampleState, WaitSet
    from cyclonedds.pub import DataWriter
    from cyclonedds.util import duration

    from cufund.apps.ros2 import idl
    from cufund.apps.ros2.config import ACK_TOPIC
    from cufund.apps.ros2.dds import QOS, DdsParticipant, QosProfile

    ap = argparse.ArgumentParser()
    ap.add_argument("--domain", type=int)
    ap.add_argument("--name")
    ap.add_argument("--out")
    args = ap.parse_args(argv)
    dds = DdsParticipant(args.domain)
    readers = {"/clock": dds.reader("/clock", "rosgraph_msgs/msg/Clock", QosProfile(depth=1000))}
    for side in SIDES:
        for what, rtype in (("image_raw", "sensor_msgs/msg/Image"), ("camera_info", "sensor_msgs/msg/CameraInfo")):
            name = f"/stereo/{side}/{what}"
            readers[name] = dds.reader(name, rtype, QosProfile(False, depth=100))
    tf_static = dds.reader("/tf_static", "tf2_msgs/msg/TFMessage", QOS["tf_static"])
    ack = DataWriter(dds.participant, dds.topic(ACK_TOPIC, "std_msgs/msg/Header"), qos=QOS["ack"].qos())
    t0 = time.monotonic()
    while time.monotonic() - t0 < 30:
        if all(len(r.get_matched_publications()) for r in readers.values()) and len(ack.get_matched_subscriptions()):
            break
        time.sleep(0.01)
    ack.write(idl.Header(idl.Time(-1, 0), args.name))
    got: dict[str, list] = {k: [] for k in [*readers, "/tf_static"]}
    waitset = WaitSet(dds.participant)
    waitset.attach(ReadCondition(readers["/clock"], SampleState.NotRead))
    order = [k for k in readers if k != "/clock"] + ["/clock"]
    last = time.monotonic()
    while time.monotonic() - last < 3.0:
        progressed = False
        for s in tf_static.take(N=100):
            if s.sample_info.valid_data:
                for tr in s.transforms:
                    v, q = tr.transform.translation, tr.transform.rotation
                    got["/tf_static"].append([tr.header.frame_id, tr.child_frame_id, v.x, v.y, v.z, q.w, q.x, q.y, q.z])
        for topic in order:
            for s in readers[topic].take(N=1000):
                if not s.sample_info.valid_data:
                    continue
                progressed = True
                if topic == "/clock":
                    got[topic].append(_ns(s.clock))
                    ack.write(idl.Header(s.clock, args.name))
                elif topic.endswith("/image_raw"):
                    data = bytes(s.data)
                    got[topic].append(
                        [
                            _ns(s.header.stamp),
                            s.header.frame_id,
                            s.width,
                            s.height,
                            s.encoding,
                            s.step,
                            hashlib.sha1(data).hexdigest(),
                            len(data),
                        ]
                    )
                else:
                    got[topic].append(
                        [
                            _ns(s.header.stamp),
                            s.header.frame_id,
                            s.width,
                            s.height,
                            s.distortion_model,
                            list(s.d),
                            list(s.k),
                            list(s.r),
                            list(s.p),
                        ]
                    )
        if progressed:
            last = time.monotonic()
        else:
            waitset.wait(duration(milliseconds=100))
    with open(args.out, "w") as f:
        json.dump(got, f)
    dds.close()
    return 0


def _quat_matrix(q_wxyz) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    w, x, y, z = q_wxyz
    return Rotation.from_quat([x, y, z, w]).as_matrix()


def test_a_stereo_rig_is_left_and_right_image_raw_with_camera_info(tmp_path):
    import cv2

    from cufund.scenarios.build import build_simulation
    from cufund.scenarios.schema import ScenarioConfig, load_scenario

    d = 1 + (os.getpid() * 7 + 27) % 140
    out = str(tmp_path / "stereo.json")
    proc = subprocess.Popen([sys.executable, __file__, "--domain", str(d), "--name", "stereo_viewer", "--out", out])
    cfg = load_scenario("square_vio")
    data = cfg.to_dict()
    data.update(duration=0.3, estimator=None)
    data["ros2"] = {"domain_id": d, "lockstep_nodes": ["stereo_viewer"], "timeout_s": 30, "rate_hz": 100.0}
    cfg = ScenarioConfig.from_dict(data, cfg.base_dir)
    sim = build_simulation(cfg).simulator
    bridge = next(c for c in sim.components if type(c).__name__ == "Ros2Bridge")
    rendered: dict[str, list] = {}  # what the rig published, as the bridge took it

    def keep(o):
        inner = o.encode

        def encode(m):
            img = np.ascontiguousarray(m.image)
            rendered.setdefault(o.topic, []).append((round(m.t * NS), hashlib.sha1(img.tobytes()).hexdigest()))
            return inner(m)

        return encode

    for o in bridge.outs:
        if o.topic.startswith("/sensors/cam"):
            o.encode = keep(o)
    try:
        sim.run(0.3)
    finally:
        bridge.close()
    assert proc.wait(timeout=60) == 0
    with open(out) as f:
        got = json.load(f)

    rig = cfg.sensors["stereo"].params.cameras(cfg.base_dir)
    left, right = got["/stereo/left/image_raw"], got["/stereo/right/image_raw"]
    assert len(left) == len(right) == len(rendered["/sensors/cam0/image"]) >= 5  # 20 Hz for 0.3 s, every frame
    assert [g[0] for g in left] == [g[0] for g in right] == [r[0] for r in rendered["/sensors/cam0/image"]]
    for cam, images in ((0, left), (1, right)):
        intr = rig[cam].intrinsics
        assert {tuple(g[1:6]) for g in images} == {
            (f"cam{cam}_optical_frame", intr.width, intr.height, "mono8", intr.width)
        }
        assert [g[6] for g in images] == [r[1] for r in rendered[f"/sensors/cam{cam}/image"]]  # the same pixels
    assert left[0][6] != right[0][6]  # two viewpoints

    infos = {side: got[f"/stereo/{side}/camera_info"] for side in SIDES}
    assert [i[0] for i in infos["left"]] == [g[0] for g in left] and [i[0] for i in infos["right"]] == [
        g[0] for g in right
    ]
    # a known point in the left optical frame (x right, y down, z forward), 3 m ahead
    X = np.array([[0.4, -0.25, 3.0]])
    # the right optical frame from the rig's mountings T_BC (camera frame FLU): optical axes x=-y_C, y=-z_C, z=x_C
    R_CO = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    R_BO = [_quat_matrix(c.T_BC.q) @ R_CO for c in rig]
    p_B = [np.asarray(c.T_BC.t, float) for c in rig]
    R_10 = R_BO[1].T @ R_BO[0]
    t_10 = R_BO[1].T @ (p_B[0] - p_B[1])
    expected = {
        "left": cv2.projectPoints(
            X, np.zeros(3), np.zeros(3), rig[0].intrinsics.K, np.array(rig[0].intrinsics.distortion)
        )[0],
        "right": cv2.projectPoints(
            X, cv2.Rodrigues(R_10)[0], t_10, rig[1].intrinsics.K, np.array(rig[1].intrinsics.distortion)
        )[0],
    }
    for side, cam in (("left", 0), ("right", 1)):
        stamp, frame, width, height, model, D, K, R, P = infos[side][0]
        intr = rig[cam].intrinsics
        assert (frame, width, height, model) == (f"cam{cam}_optical_frame", intr.width, intr.height, "plumb_bob")
        np.testing.assert_array_equal(np.reshape(K, (3, 3)), intr.K)
        assert D == list(intr.distortion)
        np.testing.assert_allclose(np.reshape(R, (3, 3)), np.eye(3), atol=1e-12)  # a parallel rig: no rotation
        x = np.reshape(P, (3, 4)) @ np.append(X[0], 1.0)
        np.testing.assert_allclose(x[:2] / x[2], expected[side].ravel(), atol=1e-9)
    P_right = np.reshape(infos["right"][0][8], (3, 4))
    assert P_right[0, 3] == pytest.approx(-P_right[0, 0] * 0.11)  # ROS's Tx = -fx' B, B the 0.11 m baseline

    # /tf_static: base_link -> camN (the log's frames) -> camN_optical_frame: z along the body's x, x to its -y
    tf = {(g[0], g[1]): g[2:] for g in got["/tf_static"]}
    for cam in (0, 1):
        T = tf[("base_link", f"cam{cam}")]
        np.testing.assert_allclose(T[:3], rig[cam].T_BC.t)
        R_BC = _quat_matrix(T[3:])
        R_CO_tf = _quat_matrix(tf[(f"cam{cam}", f"cam{cam}_optical_frame")][3:])
        np.testing.assert_allclose(R_BC @ R_CO_tf @ [0, 0, 1], [1, 0, 0], atol=1e-12)
        np.testing.assert_allclose(R_BC @ R_CO_tf @ [1, 0, 0], [0, -1, 0], atol=1e-12)
    assert ("world", "odom") in tf and ("base_link", "imu") in tf


def test_stereo_camera_info_of_a_rotated_distorted_rig_keeps_the_baseline():
    # a toed-in pair with lens distortion: P's Tx is -fx' B with B the distance between the cameras, and R
    # rotates each camera's rays into the common rectified frame (the rectified left and right rays of one
    # point have the same y: rows align)
    import cv2

    from cufund.apps.ros2.encode import stereo_camera_infos
    from cufund.sensors.kinds import StereoCameraParams

    s = np.sin(0.05 / 2)
    params = StereoCameraParams(
        intrinsics={
            "width": 640,
            "height": 480,
            "fx": 410.0,
            "fy": 405.0,
            "cx": 322.0,
            "cy": 236.0,
            "distortion": [-0.2, 0.05, 0.001, -0.0005, 0.0],
        },
        extrinsics=[
            {"p": [0.1, 0.06, 0.0], "q": [np.cos(0.05 / 2), 0.0, 0.0, -s]},
            {"p": [0.1, -0.06, 0.01], "q": [np.cos(0.05 / 2), 0.0, 0.0, s]},
        ],
    )
    rig = params.cameras()
    left, right = stereo_camera_infos(*rig)
    P1, P2 = np.reshape(left.P, (3, 4)), np.reshape(right.P, (3, 4))
    B = np.linalg.norm(np.subtract(rig[0].T_BC.t, rig[1].T_BC.t))
    assert -P2[0, 3] / P2[0, 0] == pytest.approx(B, rel=1e-9)
    # a point 4 m ahead of the body, seen raw by both cameras, lands on one row of the rectified pair
    R_CO = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    p = np.array([4.0, 0.3, -0.2])
    rows = []
    for cam, info, Pm in ((rig[0], left, P1), (rig[1], right, P2)):
        R_BO = _quat_matrix(cam.T_BC.q) @ R_CO
        X = R_BO.T @ (p - np.asarray(cam.T_BC.t))
        uv = cv2.projectPoints(
            X[None], np.zeros(3), np.zeros(3), cam.intrinsics.K, np.array(cam.intrinsics.distortion)
        )[0]
        rect = cv2.undistortPoints(uv, np.reshape(info.K, (3, 3)), np.array(info.D), R=np.reshape(info.R, (3, 3)), P=Pm)
        rows.append(rect.ravel()[1])
    assert rows[0] == pytest.approx(rows[1], abs=1e-6)


if __name__ == "__main__":
    sys.exit(node())
