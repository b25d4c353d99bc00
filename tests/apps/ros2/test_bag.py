"""ROS 2 bags: ``cufund bag`` writes a run as a rosbag2 (sqlite3 and mcap storage) that ``rosbags`` reads back with
the log's messages; ``cufund odometry`` on the bag gives what it gives on the run's log (and agrees with the
closed-loop run); bags written by ``rosbags`` itself (not by cufund) with the common LiDAR layouts and Livox's
CustomMsg are read as cufund messages; bad input is a clear error."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cufund.apps.cli import main

rosbags = pytest.importorskip("rosbags")

STORAGES = ("sqlite3", "mcap")
TIMING = {"lio_ms_per_scan_median", "lio_ms_per_scan_p99"}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A short closed-loop LIO run (its log and metrics)."""
    out = tmp_path_factory.mktemp("run") / "run"
    assert main(["run", "square_lio", "--set", "duration=6", "--out", str(out), "--no-replay"]) == 1  # timeout
    return out


@pytest.fixture(scope="module", params=STORAGES)
def bag(request, run, tmp_path_factory):
    out = tmp_path_factory.mktemp(request.param) / "bag"
    assert main(["bag", str(run), "--out", str(out), "--storage", request.param]) == 0
    return out, request.param


def _log_cdr_channels(path):
    """{topic: (ROS 2 type, [(log time, bytes)])} of the log's CDR channels, read with the official mcap reader."""
    from mcap.reader import make_reader

    out: dict[str, tuple[str, list[tuple[int, bytes]]]] = {}
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=True):
            if channel.message_encoding == "cdr":
                out.setdefault(channel.topic, (schema.name, []))[1].append((message.log_time, bytes(message.data)))
    return out


def test_a_bag_reads_back_with_rosbags_with_the_logs_messages(run, bag):
    """rosbags' own Reader (its storage plugin, its typestore built from the bag's definitions) finds every CDR
    channel of the log, with the same type, count, timestamps and bytes, and deserialises every message."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    path, storage = bag
    log = _log_cdr_channels(run / "run.mcap")
    assert {"/sensors/imu/ros", "/sensors/lidar", "/tf", "/tf_static", "/clock"} <= set(log)
    store = get_typestore(Stores.EMPTY)
    got: dict[str, list[tuple[int, bytes]]] = {}
    with Reader(path) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        for c in reader.connections:
            store.register(get_types_from_msg(c.msgdef.data, c.msgtype))
        for c, timestamp, raw in reader.messages():
            got.setdefault(c.topic, []).append((timestamp, raw))
            store.deserialize_cdr(raw, c.msgtype)  # every message decodes with the bag's own definitions
    assert types == {t: ty for t, (ty, _) in log.items()}
    for topic, (_, messages) in log.items():
        assert got[topic] == messages, topic
    import yaml

    meta = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["storage_identifier"] == storage
    assert "square_lio" in meta["custom_data"]["cufund.config"]
    with Reader(path) as reader:
        tf_static = next(c for c in reader.connections if c.topic == "/tf_static")
    assert tf_static.ext.offered_qos_profiles[0].durability.name == "TRANSIENT_LOCAL"


def test_the_standard_messages_of_a_bag_hold_the_runs_values(run, bag):
    """Decoded by rosbags, the bag's sensor_msgs/Imu hold cufund's IMU samples exactly, its PointCloud2 the LiDAR
    points (float32) with livox_ros_driver2's per-point ns timestamps."""
    from rosbags.highlevel import AnyReader

    from cufund.logs import read_mcap

    imu = [r.message for r in read_mcap(run / "run.mcap", topics=["/sensors/imu"])]
    clouds = [r.message for r in read_mcap(run / "run.mcap", topics=["/sensors/lidar"])]
    with AnyReader([bag[0]]) as reader:
        conns = [c for c in reader.connections if c.topic in ("/sensors/imu/ros", "/sensors/lidar")]
        msgs = [(c.topic, reader.deserialize(raw, c.msgtype)) for c, _, raw in reader.messages(connections=conns)]
    ros_imu = [m for t, m in msgs if t == "/sensors/imu/ros"]
    ros_clouds = [m for t, m in msgs if t == "/sensors/lidar"]
    assert len(ros_imu) == len(imu) > 1000 and len(ros_clouds) == len(clouds) > 40
    for a, m in zip(imu, ros_imu, strict=True):
        assert m.header.frame_id == "imu"
        assert m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec == round(a.t * 1e9)
        assert [m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z] == a.w_I.tolist()
        f = m.linear_acceleration
        assert [f.x, f.y, f.z] == a.f_I.tolist()
        assert m.orientation_covariance[0] == -1.0  # REP 145: no orientation
    c, m = clouds[10], ros_clouds[10]
    assert [f.name for f in m.fields] == ["x", "y", "z", "intensity", "tag", "line", "timestamp"]
    pts = np.frombuffer(
        m.data.tobytes(),
        np.dtype({"names": ["x", "y", "z"], "formats": ["<f4"] * 3, "offsets": [0, 4, 8], "itemsize": m.point_step}),
    )
    assert m.width == len(c.dt) > 1000
    np.testing.assert_array_equal(np.stack([pts["x"], pts["y"], pts["z"]], axis=1), c.points_L)


def test_cufund_odometry_on_a_bag_equals_the_run(run, bag, tmp_path, capsys):
    """The LIO open loop on the bag (sensor_msgs/Imu, PointCloud2, the truth's PoseStamped) gives the estimate
    it gives on the run's log bit for bit, and the figures agree with the closed-loop run's."""
    on_log, on_bag = tmp_path / "log", tmp_path / "bag"
    assert main(["odometry", str(run / "run.mcap"), "--out", str(on_log)]) == 0
    assert main(["odometry", str(bag[0]), "--out", str(on_bag)]) == 0
    a = json.loads((on_log / "odometry.json").read_text())
    b = json.loads((on_bag / "odometry.json").read_text())
    assert {k: v for k, v in a.items() if k not in TIMING} == {k: v for k, v in b.items() if k not in TIMING}
    assert (on_bag / "estimate.tum").read_bytes() == (on_log / "estimate.tum").read_bytes()
    assert b["lio_scans"] > 40 and b["odometry_samples"] > 500
    closed_loop = json.loads((run / "metrics.json").read_text())
    assert abs(b["odometry_rmse_m"] - closed_loop["odometry_rmse_m"]) < 0.002
    # the mountings given as a scenario file (what a bag of one's own drone needs) instead of the recorded ones
    given = tmp_path / "given"
    topics = [
        "--imu-topic",
        "/sensors/imu/ros",
        "--lidar-topic",
        "/sensors/lidar",
        "--truth-topic",
        "/truth/odometry/pose",
    ]
    assert main(["odometry", str(bag[0]), "--out", str(given), "--scenario", str(run / "config.yaml"), *topics]) == 0
    assert (given / "estimate.tum").read_bytes() == (on_log / "estimate.tum").read_bytes()
    assert b["lio_scans"] == closed_loop["lio_scans"]


def test_log_player_plays_a_bag(bag):
    """LogPlayer publishes a bag's IMU at the times the bag holds, as cufund Imu messages."""
    from cufund.logs import LogPlayer
    from cufund.logs.rosbag2_reader import read_rosbag2
    from cufund.simulator import Simulator

    topic = "/sensors/imu/ros"
    player = LogPlayer(bag[0], topics=[topic])
    assert player.topics[0].type.__name__ == "Imu"
    sim = Simulator(None, record_topics=(topic,))
    sim.add(player)
    out = sim.run(2.0).topics[topic]
    expected = [r.message for r in read_rosbag2(bag[0], [topic]) if r.log_time_ns < 2_000_000_000]
    assert len(out["t"]) == len(expected) > 300
    np.testing.assert_array_equal(out["t"], [m.t for m in expected])
    np.testing.assert_array_equal(out["f_I"], [m.f_I for m in expected])


def _rosbags_bag(path, storage, topics):
    """A bag written by rosbags alone: ``topics`` is [(topic, msgtype, [(timestamp, message)])]."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    from cufund.logs.rosbag2_reader import rosbags_typestore

    store = rosbags_typestore()
    with Writer(path, version=9, storage_plugin=StoragePlugin[storage.upper()]) as w:
        for topic, msgtype, messages in topics:
            conn = w.add_connection(topic, msgtype, typestore=store)
            for timestamp, msg in messages:
                w.write(conn, timestamp, store.serialize_cdr(msg, msgtype))
    return store


def _header(store, ns, frame):
    Time = store.types["builtin_interfaces/msg/Time"]
    return store.types["std_msgs/msg/Header"](stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame)


def _cloud2(store, ns, names, formats, values):
    """A PointCloud2 of the structured array of ``names``/``formats`` (packed) holding ``values``."""
    PointField = store.types["sensor_msgs/msg/PointField"]
    dtype = np.dtype({"names": names, "formats": formats})
    codes = {"<f4": 7, "<f8": 8, "<u4": 6, "<u2": 4, "u1": 2}
    data = np.zeros(len(values[names[0]]), dtype)
    for k in names:
        data[k] = values[k]
    fields = [
        PointField(name=k, offset=dtype.fields[k][1], datatype=codes[f], count=1)
        for k, f in zip(names, formats, strict=True)
    ]
    return store.types["sensor_msgs/msg/PointCloud2"](
        header=_header(store, ns, "os_sensor"),
        height=1,
        width=len(data),
        fields=fields,
        is_bigendian=False,
        point_step=dtype.itemsize,
        row_step=dtype.itemsize * len(data),
        data=np.frombuffer(data.tobytes(), np.uint8),
        is_dense=True,
    )


@pytest.mark.parametrize("storage", STORAGES)
def test_bags_of_other_drivers_are_read(tmp_path, storage):
    """Ouster's (uint32 ns ``t``, ``ring``, NaN gaps), Velodyne's (float32 s ``time``) PointCloud2 and Livox's
    CustomMsg, and an Imu, written by rosbags: read as PointCloud / Imu with the per-point times in seconds after
    the stamp."""
    from cufund.logs.rosbag2_reader import bag_topics, read_rosbag2

    rng = np.random.default_rng(1)
    xyz = rng.normal(size=(50, 3)).astype(np.float32)
    xyz[7] = np.nan  # an organised cloud's gap
    t0 = 1_700_000_000_123_456_789
    offsets = np.arange(50, dtype=np.uint32) * 2000  # ns
    import rosbags.typesys  # noqa: F401

    from cufund.logs.rosbag2_reader import rosbags_typestore

    store = rosbags_typestore()
    ouster = _cloud2(
        store,
        t0,
        ["x", "y", "z", "t", "ring", "intensity"],
        ["<f4", "<f4", "<f4", "<u4", "u1", "<f4"],
        {
            "x": xyz[:, 0],
            "y": xyz[:, 1],
            "z": xyz[:, 2],
            "t": offsets,
            "ring": np.arange(50) % 16,
            "intensity": np.full(50, 51.0),
        },
    )
    velodyne = _cloud2(
        store,
        t0,
        ["x", "y", "z", "intensity", "ring", "time"],
        ["<f4", "<f4", "<f4", "<f4", "<u2", "<f4"],
        {
            "x": xyz[:, 0],
            "y": xyz[:, 1],
            "z": xyz[:, 2],
            "intensity": np.zeros(50),
            "ring": np.arange(50) % 32,
            "time": offsets / 1e9,
        },
    )
    Point = store.types["livox_ros_driver2/msg/CustomPoint"]
    n_livox = 1001
    l_xyz = rng.normal(size=(n_livox, 3)).astype(np.float32)
    l_off = rng.integers(0, 100_000_000, n_livox)
    l_refl, l_line = rng.integers(0, 256, n_livox), rng.integers(0, 4, n_livox)

    def custom(timebase, count):
        return store.types["livox_ros_driver2/msg/CustomMsg"](
            header=_header(store, timebase, "livox_frame"),
            timebase=timebase,
            point_num=count,
            lidar_id=0,
            rsvd=np.zeros(3, np.uint8),
            points=[
                Point(
                    offset_time=int(l_off[i]),
                    x=float(l_xyz[i, 0]),
                    y=float(l_xyz[i, 1]),
                    z=float(l_xyz[i, 2]),
                    reflectivity=int(l_refl[i]),
                    tag=16,
                    line=int(l_line[i]),
                )
                for i in range(count)
            ],
        )

    livox, empty = custom(t0, n_livox), custom(t0 + 100_000_000, 0)
    Vector3 = store.types["geometry_msgs/msg/Vector3"]
    imu = store.types["sensor_msgs/msg/Imu"](
        header=_header(store, t0, "imu_link"),
        orientation=store.types["geometry_msgs/msg/Quaternion"](x=0, y=0, z=0, w=1),
        orientation_covariance=np.zeros(9),
        angular_velocity=Vector3(x=0.1, y=-0.2, z=0.3),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=Vector3(x=0.0, y=0.5, z=9.81),
        linear_acceleration_covariance=np.zeros(9),
    )
    path = tmp_path / "drone"
    _rosbags_bag(
        path,
        storage,
        [
            ("/ouster/points", "sensor_msgs/msg/PointCloud2", [(t0 + 100, ouster)]),
            ("/velodyne_points", "sensor_msgs/msg/PointCloud2", [(t0 + 200, velodyne)]),
            ("/livox/lidar", "livox_ros_driver2/msg/CustomMsg", [(t0 + 300, livox), (t0 + 100_000_300, empty)]),
            ("/imu/data", "sensor_msgs/msg/Imu", [(t0 + 50, imu)]),
        ],
    )
    assert bag_topics(path) == {
        "/ouster/points": "PointCloud",
        "/velodyne_points": "PointCloud",
        "/livox/lidar": "PointCloud",
        "/imu/data": "Imu",
    }
    recs = list(read_rosbag2(path))
    assert [r.topic for r in recs] == ["/imu/data", "/ouster/points", "/velodyne_points", *["/livox/lidar"] * 2]
    assert [r.log_time_ns for r in recs] == [t0 + 50, t0 + 100, t0 + 200, t0 + 300, t0 + 100_000_300]
    m = recs[0].message
    assert m.t == t0 / 1e9 and m.w_I.tolist() == [0.1, -0.2, 0.3] and m.f_I.tolist() == [0.0, 0.5, 9.81]
    keep = np.arange(50) != 7
    for r in recs[1:3]:
        c = r.message
        assert c.t == t0 / 1e9
        np.testing.assert_array_equal(c.points_L, xyz[keep])
        np.testing.assert_allclose(c.dt, offsets[keep] / 1e9, rtol=1e-6, atol=0)
        np.testing.assert_allclose(c.ranges, np.linalg.norm(xyz[keep].astype(float), axis=1))
    assert recs[1].message.channel.tolist() == (np.arange(50) % 16)[keep].tolist()
    np.testing.assert_allclose(recs[1].message.intensity, 0.2)
    c = recs[3].message
    assert c.t == t0 / 1e9 and c.dt.tolist() == (l_off / 1e9).tolist() and c.channel.tolist() == l_line.tolist()
    np.testing.assert_array_equal(c.points_L, l_xyz)
    assert c.intensity.tolist() == (l_refl / 255.0).tolist()
    assert recs[4].message.t == (t0 + 100_000_000) / 1e9 and len(recs[4].message.dt) == 0


def test_bad_input_is_a_clear_error(run, tmp_path, capsys):
    from cufund.logs.rosbag2_reader import BagReadError, read_rosbag2

    bag = tmp_path / "bag"
    assert main(["bag", str(run), "--out", str(bag)]) == 0
    capsys.readouterr()
    assert main(["bag", str(run), "--out", str(bag)]) == 2
    assert "exists already" in capsys.readouterr().err
    assert main(["bag", str(tmp_path / "nosuch"), "--out", str(tmp_path / "b2")]) == 2
    assert "no such log" in capsys.readouterr().err
    junk = tmp_path / "junk"
    junk.mkdir()
    (junk / "run.mcap").write_bytes(b"not an mcap file")
    assert main(["bag", str(junk), "--out", str(tmp_path / "b3")]) == 2
    assert "not a complete MCAP log" in capsys.readouterr().err
    with pytest.raises(BagReadError, match="is not a ROS 2 bag"):
        read_rosbag2(junk)
    with pytest.raises(BagReadError, match="topic /nosuch is not in"):
        read_rosbag2(bag, ["/nosuch"])
    with pytest.raises(BagReadError, match="rosgraph_msgs/msg/Clock, which cufund does not read"):
        read_rosbag2(bag, ["/clock"])
    assert main(["odometry", str(bag), "--out", str(tmp_path / "o"), "--lidar-topic", "/clock"]) == 2
    assert "which cufund does not read" in capsys.readouterr().err


def test_the_standard_messages_are_rosbags_cdr(run, bag):
    """The bag's (and so the log's and the bridge's) standard messages are byte for byte what rosbags' own CDR
    serialiser makes of the same values (taken from cufund's exact messages, not from those bytes): the IMU, the
    truth's and the estimate's PoseStamped, /clock and /tf."""
    from rosbags.highlevel import AnyReader

    from cufund.logs import read_mcap
    from cufund.logs.rosbag2_reader import rosbags_typestore

    store = rosbags_typestore()
    T = store.types

    def header(t, frame):
        ns = round(t * 1e9)
        return T["std_msgs/msg/Header"](
            stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame
        )

    def vec(v, kind="Vector3"):
        return T[f"geometry_msgs/msg/{kind}"](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def quat(q):
        return T["geometry_msgs/msg/Quaternion"](x=float(q[1]), y=float(q[2]), z=float(q[3]), w=float(q[0]))

    def pose(m, frame):
        return T["geometry_msgs/msg/PoseStamped"](
            header=header(m.t, frame),
            pose=T["geometry_msgs/msg/Pose"](position=vec(m.p_W, "Point"), orientation=quat(m.q_WB)),
        )

    def tf(m, parent, child):
        ts = T["geometry_msgs/msg/TransformStamped"](
            header=header(m.t, parent),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](translation=vec(m.p_W), rotation=quat(m.q_WB)),
        )
        return T["tf2_msgs/msg/TFMessage"](transforms=[ts])

    def imu(m):
        cov, unknown = np.zeros(9), np.zeros(9)
        unknown[0] = -1.0
        return T["sensor_msgs/msg/Imu"](
            header=header(m.t, "imu"),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=0.0),
            orientation_covariance=unknown,
            angular_velocity=vec(m.w_I),
            angular_velocity_covariance=cov,
            linear_acceleration=vec(m.f_I),
            linear_acceleration_covariance=cov,
        )

    log = run / "run.mcap"
    exact = {
        t: [r.message for r in read_mcap(log, topics=[t])]
        for t in ("/sensors/imu", "/truth/odometry", "/estimator/odometry")
    }
    truth, est = exact["/truth/odometry"], exact["/estimator/odometry"]
    expected = {
        "/sensors/imu/ros": [(imu(m), "sensor_msgs/msg/Imu") for m in exact["/sensors/imu"]],
        "/truth/odometry/pose": [(pose(m, "world"), "geometry_msgs/msg/PoseStamped") for m in truth],
        "/estimator/odometry/pose": [(pose(m, "odom"), "geometry_msgs/msg/PoseStamped") for m in est],
        "/clock": [
            (T["rosgraph_msgs/msg/Clock"](clock=header(m.t, "").stamp), "rosgraph_msgs/msg/Clock") for m in truth
        ],
    }
    tf_expected = sorted(
        [(round(m.t * 1e9), 0, tf(m, "world", "base_link_truth")) for m in truth]
        + [(round(m.t * 1e9), 1, tf(m, "odom", "base_link")) for m in est],
        key=lambda e: (e[0], e[1]),
    )
    with AnyReader([bag[0]]) as reader:
        conns = [c for c in reader.connections if c.topic in {*expected, "/tf"}]
        got: dict[str, list[bytes]] = {}
        for c, _, raw in reader.messages(connections=conns):
            got.setdefault(c.topic, []).append(bytes(raw))
    for topic, msgs in expected.items():
        assert len(got[topic]) == len(msgs) > 500, topic
        for raw, (msg, msgtype) in zip(got[topic], msgs, strict=True):
            assert raw == bytes(store.serialize_cdr(msg, msgtype)), topic
    serialized = {bytes(store.serialize_cdr(m, "tf2_msgs/msg/TFMessage")) for _, _, m in tf_expected}
    assert len(got["/tf"]) == len(tf_expected) and set(got["/tf"]) == serialized


def test_the_lio_on_a_played_bag_equals_it_on_the_played_log(run, bag):
    """LogPlayer on the bag, its IMU and LiDAR renamed onto the topics cufund's estimators read, feeds the LIO
    exactly as LogPlayer on the run's log does: the same estimates, bit for bit."""
    import dataclasses

    from cufund.core.config import load_yaml_text
    from cufund.estimation.kinds import lio_params
    from cufund.estimation.lio_estimator import LioEstimator
    from cufund.geometry import yaw_of
    from cufund.logs import LogPlayer, read_mcap
    from cufund.scenarios.build import ScenarioBuildContext
    from cufund.scenarios.schema import ScenarioConfig
    from cufund.simulator import Simulator

    cfg = ScenarioConfig.from_dict(load_yaml_text((run / "config.yaml").read_text(), "config"))
    params, imu, lidar = lio_params(cfg.estimator.params, ScenarioBuildContext(cfg))
    truth = next(r.message for r in read_mcap(run / "run.mcap", topics=["/truth/odometry"]))
    params = dataclasses.replace(params, p_WB0=tuple(truth.p_W), pad_yaw=yaw_of(truth.q_WB))

    def estimates(player):
        sim = Simulator(None, record_topics=("/estimator/odometry",))
        sim.add(player)
        sim.add(LioEstimator(params, imu_topic=imu.topic, lidar_topic=lidar.topic))
        return sim.run(4.0).topics["/estimator/odometry"]

    on_log = estimates(LogPlayer(run / "run.mcap", topics=[imu.topic, lidar.topic]))
    on_bag = estimates(LogPlayer(bag[0], topics={f"{imu.topic}/ros": imu.topic, lidar.topic: lidar.topic}))
    assert len(on_log["t"]) > 300
    for field in ("t", "p_W", "v_W", "q_WB"):
        assert np.asarray(on_bag[field]).tobytes() == np.asarray(on_log[field]).tobytes(), field


def _imu_bag(path, storage, n):
    """A bag written by rosbags of ``n`` sensor_msgs/Imu on /imu (angular_velocity.z = 1000.5 + i)."""
    from cufund.logs.rosbag2_reader import rosbags_typestore

    T = rosbags_typestore().types
    Vector3 = T["geometry_msgs/msg/Vector3"]
    msgs = [
        T["sensor_msgs/msg/Imu"](
            header=_header(rosbags_typestore(), 10**9 + i, "imu"),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0, y=0, z=0, w=1),
            orientation_covariance=np.zeros(9),
            angular_velocity=Vector3(x=0.0, y=0.0, z=1000.5 + i),
            angular_velocity_covariance=np.zeros(9),
            linear_acceleration=Vector3(x=0.0, y=0.0, z=9.81),
            linear_acceleration_covariance=np.zeros(9),
        )
        for i in range(n)
    ]
    _rosbags_bag(path, storage, [("/imu", "sensor_msgs/msg/Imu", [(10**9 + i, m) for i, m in enumerate(msgs)])])


def test_a_damaged_bag_is_a_clear_error_while_reading(tmp_path, capsys):
    """The first record of an MCAP-stored bag with a length past its chunk (a damaged file that still opens) is a
    BagReadError naming the bag, and `cufund odometry` on it exits 2 with it, not a traceback of rosbags' own."""
    import struct

    from cufund.logs.rosbag2_reader import BagReadError, read_rosbag2

    path = tmp_path / "damaged"
    _imu_bag(path, "mcap", 50)
    assert len(list(read_rosbag2(path))) == 50
    mcap = next(path.glob("*.mcap"))
    data = bytearray(mcap.read_bytes())
    # the first Message record: opcode 0x05, uint64 length, uint16 channel, uint32 sequence, log and publish time
    at = data.find(struct.pack("<QQ", 10**9, 10**9)) - 15
    assert data[at] == 0x05 and struct.unpack_from("<Q", data, at + 1)[0] < 1000
    struct.pack_into("<Q", data, at + 1, 1 << 40)
    mcap.write_bytes(bytes(data))
    with pytest.raises(BagReadError, match="cannot read the bag's messages"):
        list(read_rosbag2(path))
    capsys.readouterr()
    args = ["--imu-topic", "/imu", "--lidar-topic", "/imu", "--truth-topic", "/imu"]
    assert main(["odometry", str(path), "--out", str(tmp_path / "o"), *args]) == 2
    assert "cannot read the bag's messages" in capsys.readouterr().err


def test_custom_data_that_is_not_text_is_refused(tmp_path, capsys):
    """A metadata.yaml whose custom_data holds a list built of aliases (each level ten of the previous: text of
    10^6 items here, 10^9 and a hang a few lines further) is refused by name before any of it is made text; strings
    and scalars are read."""
    from cufund.logs.rosbag2_reader import BagReadError, bag_custom_data

    path = tmp_path / "bag"
    _imu_bag(path, "sqlite3", 2)
    meta = (path / "metadata.yaml").read_text()
    assert "custom_data: null" in meta
    levels = ["a: &a [x, x, x, x, x, x, x, x, x, x]"]
    for prev, name in zip("abcde", "bcdef", strict=True):
        levels.append(f"{name}: &{name} [{', '.join([f'*{prev}'] * 10)}]")
    laughs = meta.replace("custom_data: null", "custom_data:\n    version: 2\n    " + "\n    ".join(levels))
    (path / "metadata.yaml").write_text(laughs)
    with pytest.raises(BagReadError, match="custom_data 'a' is not a string"):
        bag_custom_data(path)
    assert main(["odometry", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "custom_data 'a' is not a string" in capsys.readouterr().err
    (path / "metadata.yaml").write_text(meta.replace("custom_data: null", "custom_data:\n    n: 2\n    s: text"))
    assert bag_custom_data(path) == {"n": "2", "s": "text"}


def test_a_pointcloud2_field_past_its_point_step_is_refused(tmp_path):
    """A PointCloud2 whose field lies past its point_step (z at byte 100 of a 12-byte point) is a BagReadError
    naming the message and its fields, not numpy's error about a dtype."""
    from cufund.logs.rosbag2_reader import BagReadError, read_rosbag2, rosbags_typestore

    store = rosbags_typestore()
    cloud = _cloud2(store, 10**9, ["x", "y", "z"], ["<f4"] * 3, {k: np.zeros(4) for k in "xyz"})
    cloud.fields[2].offset = 100
    path = tmp_path / "bag"
    _rosbags_bag(path, "sqlite3", [("/points", "sensor_msgs/msg/PointCloud2", [(10**9, cloud)])])
    with pytest.raises(BagReadError, match=r"topic /points at 1000000000 ns: .*offsets.*\('z', 100, 7\)"):
        list(read_rosbag2(path))


def test_a_log_that_fails_midway_leaves_no_bag(run, tmp_path, capsys):
    """`cufund bag` on a log that turns out damaged after its start (the last 40 % cut off) exits 2 and leaves no
    folder behind: a partial bag would read as a complete one (its metadata.yaml written), and a second try would
    be refused as existing."""
    log = tmp_path / "cut" / "run.mcap"
    log.parent.mkdir()
    data = (run / "run.mcap").read_bytes()
    log.write_bytes(data[: int(len(data) * 0.6)])
    from cufund.logs.mcap_reader import TruncatedLogWarning

    out = tmp_path / "bag"
    capsys.readouterr()
    with pytest.warns(TruncatedLogWarning):  # the log's metadata is read from the start it keeps
        assert main(["bag", str(log.parent), "--out", str(out)]) == 2
    assert "not a complete MCAP log" in capsys.readouterr().err
    assert not out.exists()


def test_a_hostile_bag_folder_is_refused_without_running_anything(tmp_path):
    """A metadata.yaml with a Python tag is refused by both YAML readers (rosbags', cufund's custom_data) without
    calling what it names; a sqlite3 bag with a table of its own is read, one whose topics table lacks ROS 2's
    columns is a BagReadError."""
    import sqlite3

    from cufund.logs.rosbag2_reader import BagReadError, bag_custom_data, bag_topics, read_rosbag2

    path = tmp_path / "bag"
    _imu_bag(path, "sqlite3", 3)
    meta = (path / "metadata.yaml").read_text()
    marker = tmp_path / "ran"
    (path / "metadata.yaml").write_text(f"!!python/object/apply:os.system ['touch {marker}']\n")
    with pytest.raises(BagReadError, match="python/object/apply"):
        bag_topics(path)
    with pytest.raises(BagReadError, match="python/object/apply"):
        bag_custom_data(path)
    assert not marker.exists()
    (path / "metadata.yaml").write_text(meta)
    (db,) = path.glob("*.db3")
    con = sqlite3.connect(db)
    con.execute("CREATE TABLE extra (x)")
    con.commit()
    assert len(list(read_rosbag2(path))) == 3
    con.execute("DROP TABLE topics")
    con.execute("CREATE TABLE topics (id INTEGER, name TEXT)")
    con.commit()
    con.close()
    with pytest.raises(BagReadError, match="cannot open the ROS 2 bag: .*no such column"):
        bag_topics(path)


@pytest.mark.parametrize("storage", STORAGES)
def test_a_bag_whose_storage_is_a_fifo_is_refused_at_once(tmp_path, storage):
    """A bag folder whose storage file is a FIFO (or a link to a device) is a BagReadError naming it: opening the
    FIFO blocked the reader for ever."""
    import os
    import threading

    from cufund.logs.rosbag2_reader import BagReadError, bag_topics

    path = tmp_path / "bag"
    _imu_bag(path, storage, 2)
    (db,) = [p for p in path.iterdir() if p.name != "metadata.yaml"]
    db.unlink()
    os.mkfifo(db)
    errors: list[BaseException] = []

    def read() -> None:
        try:
            bag_topics(path)
        except BaseException as exc:
            errors.append(exc)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(timeout=20)
    if reader.is_alive():  # blocked in open(): a writer coming and going lets it go on
        os.close(os.open(db, os.O_WRONLY | os.O_NONBLOCK))
        reader.join(timeout=20)
        pytest.fail("reading a bag whose storage is a FIFO blocked")
    (error,) = errors
    assert isinstance(error, BagReadError) and f"{db.name} is not a regular file" in str(error)
    db.unlink()
    db.symlink_to("/dev/zero")
    with pytest.raises(BagReadError, match="is not a regular file"):
        bag_topics(path)


def test_a_livox_custommsg_of_another_definition_is_refused(tmp_path):
    """A bag whose own livox_ros_driver2 CustomPoint definition has another layout (a fork's extra float32) is a
    BagReadError naming it: the fast reader assumes the driver's 19-byte point and read such points as garbage."""
    from rosbags.rosbag2 import Writer
    from rosbags.typesys import get_types_from_msg

    from cufund.logs.rosbag2_reader import LIVOX_MSGS, BagReadError, read_rosbag2, rosbags_typestore

    store = rosbags_typestore()
    point = "livox_ros_driver2/msg/CustomPoint"
    fork = get_types_from_msg(LIVOX_MSGS[point].replace("uint8 line", "float32 noise\nuint8 line"), point)
    store.fielddefs.pop(point)
    store.register(fork)
    Point, Msg = store.types[point], store.types["livox_ros_driver2/msg/CustomMsg"]
    msg = Msg(
        header=_header(store, 10**9, "livox_frame"),
        timebase=10**9,
        point_num=2,
        lidar_id=0,
        rsvd=np.zeros(3, np.uint8),
        points=[Point(offset_time=k, x=1.0, y=2.0, z=3.0, reflectivity=9, tag=0, noise=0.5, line=1) for k in (0, 1)],
    )
    path = tmp_path / "bag"
    with Writer(path, version=9) as w:
        conn = w.add_connection("/livox/lidar", "livox_ros_driver2/msg/CustomMsg", typestore=store)
        w.write(conn, 10**9, store.serialize_cdr(msg, "livox_ros_driver2/msg/CustomMsg"))
    with pytest.raises(BagReadError, match="definition of livox_ros_driver2/msg/CustomPoint is not the Livox"):
        list(read_rosbag2(path))
