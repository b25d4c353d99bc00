"""The logged estimate as a proper ``nav_msgs/msg/Odometry`` (``<topic>/ros``), decoded by rosbags: the pose in the
parent frame, the twist in the child (body) frame as REP 105 says (``v_B = R_WB^T v_W``, checked against scipy),
the body rate, and the covariances an estimator gives (square_mocap's ESKF: its P, mapped independently here)."""

from __future__ import annotations

import numpy as np
import pytest
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


def _skew(a):
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


@pytest.fixture(scope="module")
def mocap_run(tmp_path_factory):
    """A 4 s square_mocap run folder, the ESKF's P at each estimate it published (by stamp) and the filter."""
    from cufund.estimation.imu_propagator import ImuPropagator
    from cufund.scenarios.build import build_simulation
    from cufund.scenarios.run_folder import run_into_folder
    from cufund.scenarios.schema import load_scenario

    built = build_simulation(load_scenario("square_mocap", {"duration": 4.0}))
    (eskf,) = [c for c in built.simulator.components if isinstance(c, ImuPropagator)]
    published = {}
    estimate = eskf.estimate

    def spy(t, bus):
        out = estimate(t, bus)
        if out is not None:
            published[out.t] = eskf.covariance
        return out

    eskf.estimate = spy
    out = tmp_path_factory.mktemp("square_mocap")
    run_into_folder(built, out, plots=False, replay=False)
    return out, published, eskf


def test_square_mocap_logs_the_eskf_covariance_and_body_velocity(mocap_run):
    """square_mocap's error-state filter: every logged nav_msgs/Odometry has the twist of its estimate in the body
    frame and the covariances of the filter's P at that instant (recorded as the filter published), mapped here
    independently: pose [dp_W, R dtheta_B], twist [R^T dv_W + v_B x' dtheta_B, -db_g] plus the gyro's sample noise."""
    from cufund.logs import read_mcap

    run, published, eskf = mocap_run
    exact = [r.message for r in read_mcap(run / "run.mcap", topics=["/estimator/odometry"])]
    got = _ros_odometry(run / "run.mcap")
    assert len(got) == len(exact) > 500
    gyro = eskf.params.gyro_noise_density**2 * eskf.rate_hz
    for m, g in zip(exact, got, strict=True):
        R = Rotation.from_quat(np.r_[m.q_WB[1:], m.q_WB[0]]).as_matrix()
        v_B = R.T @ m.v_W
        np.testing.assert_allclose(_xyz(g.twist.twist.linear), v_B, atol=1e-12)
        P = published[m.t]
        J = np.zeros((12, 15))
        J[0:3, 0:3], J[3:6, 6:9] = np.eye(3), R
        J[6:9, 3:6], J[6:9, 6:9], J[9:12, 12:15] = R.T, _skew(v_B), -np.eye(3)
        C = J @ P @ J.T + np.diag([0.0] * 9 + [gyro] * 3)
        scale = np.abs(C).max()
        np.testing.assert_allclose(g.pose.covariance.reshape(6, 6), C[0:6, 0:6], rtol=1e-9, atol=1e-12 * scale)
        np.testing.assert_allclose(g.twist.covariance.reshape(6, 6), C[6:12, 6:12], rtol=1e-9, atol=1e-12 * scale)
        np.testing.assert_array_equal(g.pose.covariance.reshape(6, 6), m.pose_cov_W)  # the exact channel's
    sigma_p = np.sqrt(np.diag(m.pose_cov_W)[:3])
    assert (sigma_p < 0.002).all()  # motion capture's 0.5 mm: the filter knows its position to about that


def test_a_bag_of_the_run_reads_back_the_estimate_and_its_covariances(mocap_run, tmp_path):
    """cufund bag, then the rosbag2 reader on its nav_msgs/Odometry: the world velocity and both covariances of
    the run's estimate (twist rotated back from the body)."""
    from cufund.apps.ros2.bag import write_bag
    from cufund.logs import read_mcap
    from cufund.logs.rosbag2_reader import read_rosbag2

    run, _, _ = mocap_run
    write_bag(run / "run.mcap", tmp_path / "bag")
    exact = [r.message for r in read_mcap(run / "run.mcap", topics=["/estimator/odometry"])]
    back = [r.message for r in read_rosbag2(tmp_path / "bag", topics=["/estimator/odometry/ros"])]
    assert len(back) == len(exact) > 500
    for m, b in zip(exact, back, strict=True):
        np.testing.assert_allclose(b.v_W, m.v_W, atol=1e-12)
        np.testing.assert_array_equal(b.pose_cov_W, m.pose_cov_W)
        np.testing.assert_array_equal(b.twist_cov_B, m.twist_cov_B)


def test_covariances_take_room_only_on_a_topic_whose_first_message_has_them(tmp_path):
    """The truth (no covariance) keeps its rows as they were; a covariance appearing later on such a topic is a
    ValueError naming the field, not dropped in silence; on a topic with them, a row without them is all zero."""
    from cufund.logs import read_mcap

    C = np.arange(36.0).reshape(6, 6)
    m = lambda t, **cov: M.Odometry(t, np.zeros(3), np.ones(3), np.array([1.0, 0, 0, 0]), np.zeros(3), **cov)  # noqa: E731
    with McapLogger(tmp_path / "o.mcap") as log:
        log.write("/estimator/odometry", m(0.0, pose_cov_W=C, twist_cov_B=C + 100), 0, 0)
        log.write("/estimator/odometry", m(0.1), 1, 1)
        log.write("/truth/odometry", m(0.0), 0, 0)
        with pytest.raises(ValueError, match="'pose_cov_W'.*first message"):
            log.write("/truth/odometry", m(0.1, pose_cov_W=C), 1, 1)
    est = [r.message for r in read_mcap(tmp_path / "o.mcap", topics=["/estimator/odometry"])]
    np.testing.assert_array_equal(est[0].pose_cov_W, C)
    np.testing.assert_array_equal(est[0].twist_cov_B, C + 100)
    assert est[1].pose_cov_W is None and est[1].twist_cov_B is None
    with open(tmp_path / "o.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    layout = {c.topic: c.metadata.get("cufund.layout", "") for c in summary.channels.values()}
    assert "pose_cov_W" in layout["/estimator/odometry"] and "pose_cov_W" not in layout["/truth/odometry"]
    ros = _ros_odometry(tmp_path / "o.mcap")
    np.testing.assert_array_equal(ros[0].pose.covariance, C.ravel())
    np.testing.assert_array_equal(ros[0].twist.covariance, C.ravel() + 100)
    assert not ros[1].pose.covariance.any() and not ros[1].twist.covariance.any()
