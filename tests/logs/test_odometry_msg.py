"""The logged estimate as a proper ``nav_msgs/msg/Odometry`` (``<topic>/ros``), decoded by rosbags: the pose in the
parent frame, the twist in the child (body) frame as REP 105 says (``v_B = R_WB^T v_W``, checked against scipy),
the body rate."""

from __future__ import annotations

import numpy as np
from mcap.reader import make_reader
from rosbags.typesys import Stores, get_typestore
from scipy.spatial.transform import Rotation

from cufund import messages as M
from cufund.logs import McapLogger

STORE = get_typestore(Stores.ROS2_HUMBLE)


def _ros_odometry(path, topic="/estimator/odometry/ros"):
    with open(path, "rb") as f:
        return [
            STORE.deserialize_cdr(msg.data, "nav_msgs/msg/Odometry")
            for _, _, msg in make_reader(f).iter_messages(topics=[topic])
        ]


def _xyz(v):
    return np.array([v.x, v.y, v.z])


def test_twist_linear_is_the_world_velocity_in_the_body_frame(tmp_path):
    rng = np.random.default_rng(3)
    sent = []
    with McapLogger(tmp_path / "o.mcap") as log:
        for i in range(40):
            q = rng.normal(size=4) * (0.5 + rng.random())  # not normalised: the view normalises it
            m = M.Odometry(0.01 * i, rng.normal(size=3), rng.normal(size=3) * 3, q, rng.normal(size=3))
            sent.append(m)
            log.write("/estimator/odometry", m, 10_000_000 * i, 10_000_000 * i)
    got = _ros_odometry(tmp_path / "o.mcap")
    assert len(got) == len(sent)
    for m, g in zip(sent, got, strict=True):
        R_WB = Rotation.from_quat(np.r_[m.q_WB[1:], m.q_WB[0]])  # scipy: x, y, z, w
        np.testing.assert_allclose(_xyz(g.twist.twist.linear), R_WB.inv().apply(np.array(m.v_W)), atol=1e-12)
        np.testing.assert_array_equal(_xyz(g.twist.twist.angular), m.w_B)
        np.testing.assert_array_equal(_xyz(g.pose.pose.position), m.p_W)
        assert g.header.frame_id == "odom" and g.child_frame_id == "base_link"
        assert not g.pose.covariance.any() and not g.twist.covariance.any()  # none given: all zero, unknown


def test_a_zero_quaternion_gives_a_nan_twist_not_garbage(tmp_path):
    with McapLogger(tmp_path / "o.mcap") as log:
        log.write("/estimator/odometry", M.Odometry(0.0, np.zeros(3), np.ones(3), np.zeros(4), np.zeros(3)), 0, 0)
    (g,) = _ros_odometry(tmp_path / "o.mcap")
    assert np.isnan(_xyz(g.twist.twist.linear)).all()
