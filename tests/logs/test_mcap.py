"""MCAP logs: every message type round-trips bit for bit, the file is what the official ``mcap`` reader, the ROS 2
CDR decoder and Foxglove's JSON schemas expect, memory stays bounded, and a damaged file gives a clear error."""

from __future__ import annotations

import dataclasses
import enum
import tracemalloc

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from cufund import messages as M
from cufund.logs import LogRecord, McapLogger, McapReadError, TruncatedLogWarning, log_topics, read_mcap


class Color(enum.Enum):
    RED = "red"
    BLUE = 2


@dataclasses.dataclass(frozen=True)
class Inner:
    gain: float
    name: str


@dataclasses.dataclass(frozen=True)
class UserMessage:
    """Not a cufund message, with fields no fixed layout holds: the JSON codec takes it."""

    t: float
    label: str
    color: Color
    inner: Inner
    grid: np.ndarray
    counts: tuple
    extra: dict
    maybe: float | None = None


@dataclasses.dataclass(frozen=True)
class UserFixed:
    """A user dataclass of numbers and fixed arrays: logged as exact CDR."""

    t: float
    k: int
    ok: bool
    R_WB: np.ndarray
    ids: np.ndarray


def _stream(rng: np.random.Generator) -> list[tuple[str, object]]:
    """Messages of every type on their topics, several per topic, many sharing a stamp."""
    out: list[tuple[str, object]] = []
    v3 = lambda: rng.normal(size=3)  # noqa: E731
    for i in range(9):
        t = 0.01 * i + rng.random() * 1e-3  # stamps with full float64 mantissas
        q = rng.normal(size=4)
        out += [
            ("/truth/odometry", M.Odometry(t, v3(), v3(), q / np.linalg.norm(q), v3(), v3(), v3())),
            ("/estimator/odometry", M.Odometry(t, v3(), v3(), q, v3(), v3() if i % 4 == 3 else None)),
            ("/sensors/imu", M.Imu(t, v3(), v3())),
            ("/sensors/magnetometer", M.MagneticField(t, v3() * 1e-5)),
            ("/sensors/barometer", M.AirPressure(t, 101325.0 + rng.normal(), rng.normal(), 288.15)),
            (
                "/sensors/gps",
                M.GpsFix(t, 47.3 + rng.random(), 8.5, 500.0 + rng.random(), v3(), 3, 11, 0.8, 1.3)
                if i % 3
                else M.GpsFix(t, np.nan, np.nan, np.nan, np.full(3, np.nan), 0, 0, np.inf, np.inf),
            ),
            ("/setpoint/trajectory", M.TrajectorySetpoint(t, v3(), v3(), v3(), v3(), rng.normal(), 0.0)),
            ("/setpoint/attitude", M.AttitudeSetpoint(t, q, 0.3 + rng.random(), -0.1)),
            ("/setpoint/rates", M.RateSetpoint(t, v3(), 0.31)),
            ("/setpoint/thrust_torque", M.ThrustTorqueSetpoint(t, 0.29, v3() * 1e-3)),
            ("/actuator/command", M.ActuatorCommand(t, 2000.0 + rng.random(4))),
            (
                "/user/fixed",
                UserFixed(
                    t, -(2**62) + i, i % 2 == 0, rng.normal(size=(3, 3)), rng.integers(-5, 5, 4).astype(np.int32)
                ),
            ),
        ]
        if i % 3 == 0:
            n = 50 + 7 * i
            out += [
                ("/commander/flight_mode", M.FlightModeCommand(t, list(M.FlightMode)[i % 3])),
                (
                    "/sensors/lidar",
                    M.PointCloud(
                        t,
                        np.sort(rng.random(n)) * 0.1,
                        rng.normal(size=(n, 3)).astype(np.float32),
                        rng.random(n) * 40,
                        rng.random(n),
                        rng.integers(0, 32, n).astype(np.int32),
                        i,
                    ),
                ),
                (
                    "/truth/point_cloud",
                    M.LidarTruth(t, rng.normal(size=(n, 3)).astype(np.float32), rng.integers(0, 2**32, n, np.uint32)),
                ),
                (
                    "/sensors/depth_image",
                    M.CameraImage(t, np.where(rng.random((6, 8)) < 0.2, np.nan, rng.random((6, 8))).astype(np.float32)),
                ),
                ("/sensors/rgb_image", M.CameraImage(t, rng.integers(0, 256, (6, 8, 3)).astype(np.uint8))),
                (
                    "/user/json",
                    UserMessage(
                        t,
                        'a "label" ünïcode',
                        Color.BLUE if i else Color.RED,
                        Inner(-np.inf, "x"),
                        rng.normal(size=(2, 40)),
                        (1, 2.5, "s"),
                        {"k": [1, None]},
                        None if i else 3.5,
                    ),
                ),
            ]
    return out


def _same(a: object, b: object) -> bool:
    """Equal type and value, arrays by dtype, shape and bytes, floats by bits (NaN equals NaN)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    if isinstance(a, float):
        return np.float64(a).tobytes() == np.float64(b).tobytes()
    if dataclasses.is_dataclass(a):
        return all(_same(getattr(a, f.name), getattr(b, f.name)) for f in dataclasses.fields(a))
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return a == b


VIEWS = {"/truth/odometry": 3, "/estimator/odometry": 3, "/sensors/imu": 1, "/sensors/gps": 1}
"""Standard messages derived from each message of these topics: truth pose, /tf, /clock; the estimate's
nav_msgs/Odometry, pose, /tf; sensor_msgs/Imu; NavSatFix."""


def _n_views(written) -> int:
    return sum(VIEWS.get(topic, 0) for topic, *_ in written)


def _write(path, stream, **options) -> list[tuple[str, object, int, int]]:
    written = []
    with McapLogger(path, {"scenario": "unit", "seed": "3"}, **options) as log:
        for k, (topic, message) in enumerate(stream):
            log_ns = int(round(message.t * 1e9)) // 1_000_000 * 1_000_000 + 10  # ms buckets: many ties
            written.append((topic, message, log_ns, log_ns - k % 5))
            log.write(topic, message, log_ns, log_ns - k % 5)
    return written


@pytest.fixture(scope="module")
def log_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("mcap") / "run.mcap"
    written = _write(path, _stream(np.random.default_rng(7)), block_messages=4, compression="zstd")
    return path, written


LOGGED_AS_ROS = ("/sensors/lidar", "/truth/point_cloud", "/sensors/depth_image", "/sensors/rgb_image")
"""Topics logged as standard ROS 2 messages only (PointCloud2, Image): read back to the nanosecond stamp."""


def _as_logged(message: object) -> object:
    """What a cloud or image reads back as (the documented losses of the ROS 2 messages, computed independently):
    the stamp to the nanosecond, a cloud's intensity to Livox's 0-255 steps, its ranges the points' norms, no
    pattern index."""
    t = round(message.t * 1e9) / 1e9
    if isinstance(message, M.PointCloud):
        return dataclasses.replace(
            message,
            t=t,
            intensity=np.round(message.intensity * 255) / 255,
            ranges=np.linalg.norm(message.points_L.astype(np.float64), axis=1),
            frame=-1,
        )
    return dataclasses.replace(message, t=t)


def test_every_message_type_round_trips_exactly_in_log_time_then_write_order(log_file):
    path, written = log_file
    records = list(read_mcap(path))
    expected = sorted(written, key=lambda w: w[2])  # stable: ties keep the write order
    assert [(r.topic, r.log_time_ns, r.publish_time_ns) for r in records] == [(t, a, b) for t, _, a, b in expected]
    for record, (topic, message, _, _) in zip(records, expected, strict=True):
        assert isinstance(record, LogRecord)
        if topic not in LOGGED_AS_ROS:
            assert _same(record.message, message), (topic, record.message, message)
            continue
        logged = _as_logged(message)
        got = record.message
        if isinstance(message, M.PointCloud):  # per-point times in whole nanoseconds
            assert np.allclose(got.dt, message.dt, rtol=0, atol=0.5e-9) and got.dt.dtype == message.dt.dtype
            got = dataclasses.replace(got, dt=message.dt)
        assert _same(got, logged), (topic, got, logged)
    assert isinstance(records[0].message.p_W, np.ndarray) and not records[0].message.p_W.flags.writeable


def test_topic_selection_and_topic_listing(log_file):
    path, written = log_file
    only = list(read_mcap(path, topics=["/sensors/imu", "/user/json"]))
    assert [r.topic for r in only] == [
        t for t, *_ in sorted(written, key=lambda w: w[2]) if t in ("/sensors/imu", "/user/json")
    ]
    topics = log_topics(path)
    assert topics["/truth/odometry"] == "Odometry" and topics["/user/json"] == "UserMessage"
    assert "/truth/odometry/pose" not in topics and "/tf" not in topics  # views, not logged topics
    with pytest.raises(ValueError, match="/no/such/topic"):
        read_mcap(path, topics="/no/such/topic")


def test_official_reader_sees_a_valid_indexed_file(log_file):
    path, written = log_file
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        messages = list(reader.iter_messages(log_time_order=False))
        metadata = list(reader.iter_metadata())
        ordered = [m.log_time for _, _, m in reader.iter_messages(log_time_order=True)]
    n_views = _n_views(written)
    assert len(messages) == summary.statistics.message_count == len(written) + n_views
    assert sum(summary.statistics.channel_message_counts.values()) == len(messages)
    assert summary.statistics.chunk_count == len(summary.chunk_indexes) > 10
    assert [(m.name, m.metadata) for m in metadata] == [("cufund", {"scenario": "unit", "seed": "3"})]
    times = sorted(m.log_time for _, _, m in messages)
    assert ordered == times  # the reader merges chunks by their indexed start times: they are right
    statistics = summary.statistics
    assert min(i.message_start_time for i in summary.chunk_indexes) == times[0] == statistics.message_start_time
    assert max(i.message_end_time for i in summary.chunk_indexes) == times[-1] == statistics.message_end_time


def test_message_indexes_point_at_their_messages(log_file):
    """Read record by record (the streaming reader, CRCs checked): every Message Index entry is the log time and
    offset of a Message record of its channel in the decompressed chunk before it."""
    import struct

    import zstandard
    from mcap.records import Chunk, DataEnd, Footer, Header, MessageIndex
    from mcap.stream_reader import StreamReader

    path, written = log_file
    with open(path, "rb") as f:
        records = list(StreamReader(f, emit_chunks=True, validate_crcs=True).records)
    assert isinstance(records[0], Header) and isinstance(records[-1], Footer)
    assert any(isinstance(r, DataEnd) for r in records)
    checked = 0
    chunk_data = b""
    for record in records:
        if isinstance(record, Chunk):
            assert record.compression == "zstd"
            chunk_data = zstandard.ZstdDecompressor().decompress(record.data, record.uncompressed_size)
            assert len(chunk_data) == record.uncompressed_size
        elif isinstance(record, MessageIndex):
            times = [t for t, _ in record.records]
            assert times == sorted(times)
            for log_time, offset in record.records:
                opcode, _, channel, _, stamp = struct.unpack_from("<BQHIQ", chunk_data, offset)
                assert (opcode, channel, stamp) == (0x05, record.channel_id, log_time)
                checked += 1
    assert checked == sum(1 for _ in read_mcap(path)) + _n_views(written)


def _schemas(path):
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    return {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}, summary


def test_schema_names_are_ros2_and_foxglove_well_known_ones(log_file):
    path, _ = log_file
    schemas, summary = _schemas(path)
    names = {topic: s.name for topic, s in schemas.items()}
    assert names["/tf"] == "tf2_msgs/msg/TFMessage" and names["/clock"] == "rosgraph_msgs/msg/Clock"
    assert names["/truth/odometry/pose"] == names["/estimator/odometry/pose"] == "geometry_msgs/msg/PoseStamped"
    assert names["/estimator/odometry/ros"] == "nav_msgs/msg/Odometry"
    assert names["/sensors/lidar"] == names["/truth/point_cloud"] == "sensor_msgs/msg/PointCloud2"
    assert names["/sensors/depth_image"] == names["/sensors/rgb_image"] == "sensor_msgs/msg/Image"
    assert (
        names["/sensors/imu/ros"] == "sensor_msgs/msg/Imu" and names["/sensors/gps/ros"] == "sensor_msgs/msg/NavSatFix"
    )
    assert names["/truth/odometry"] == "cufund_msgs/msg/Odometry"
    assert names["/user/json"] == "cufund.UserMessage"
    encodings = {c.topic: c.message_encoding for c in summary.channels.values()}
    assert all(encodings[t] == "cdr" for t, name in names.items() if not name.startswith("cufund."))
    assert encodings["/user/json"] == "json"
    assert [c.topic for c in summary.channels.values()].count("/tf") == 1  # one /tf channel, both sources


def _decoded(path) -> dict[str, list]:
    """Every CDR message decoded by mcap-ros2-support (from the ros2msg schemas alone), by topic."""
    factory = DecoderFactory()
    seen: dict[str, list] = {}
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            if channel.message_encoding == "cdr":
                decode = factory.decoder_for("cdr", schema)
                seen.setdefault(channel.topic, []).append(decode(message.data))
    return seen


def test_cdr_channels_decode_with_the_ros2_decoder_to_the_logged_values(log_file):
    path, written = log_file
    truth = [m for t, m, *_ in written if t == "/truth/odometry"]
    estimate = [m for t, m, *_ in written if t == "/estimator/odometry"]
    fixed = [m for t, m, *_ in written if t == "/user/fixed"]
    imus = [m for t, m, *_ in written if t == "/sensors/imu"]
    seen = _decoded(path)
    tf = {(m.transforms[0].header.frame_id, m.transforms[0].child_frame_id): [] for m in seen["/tf"]}
    for m in seen["/tf"]:
        assert len(m.transforms) == 1
        tf[(m.transforms[0].header.frame_id, m.transforms[0].child_frame_id)].append(m.transforms[0])
    assert set(tf) == {("world", "base_link_truth"), ("odom", "base_link")}
    for odometry, transform, pose in zip(
        truth, tf["world", "base_link_truth"], seen["/truth/odometry/pose"], strict=True
    ):
        p, q = odometry.p_W, odometry.q_WB
        r = transform.transform
        assert [r.translation.x, r.translation.y, r.translation.z] == list(p)
        assert [r.rotation.w, r.rotation.x, r.rotation.y, r.rotation.z] == list(q)  # ROS x, y, z, w
        assert pose.header.frame_id == "world" and [pose.pose.position.x, pose.pose.orientation.w] == [p[0], q[0]]
        assert transform.header.stamp.sec + transform.header.stamp.nanosec * 1e-9 == pytest.approx(odometry.t, abs=1e-9)
    assert [c.clock.nanosec for c in seen["/clock"]] == [round(o.t * 1e9) % 10**9 for o in truth]
    for odometry, ros in zip(estimate, seen["/estimator/odometry/ros"], strict=True):
        assert (ros.header.frame_id, ros.child_frame_id) == ("odom", "base_link")
        o = ros.pose.pose.orientation
        assert [o.w, o.x, o.y, o.z] == list(odometry.q_WB)
        assert [ros.twist.twist.angular.x, ros.twist.twist.angular.z] == [odometry.w_B[0], odometry.w_B[2]]
        assert list(ros.pose.covariance) == [0.0] * 36  # the estimators publish no covariance
    for imu, ros in zip(imus, seen["/sensors/imu/ros"], strict=True):
        assert ros.header.frame_id == "imu" and ros.orientation_covariance[0] == -1.0
        assert [ros.linear_acceleration.x, ros.angular_velocity.z] == [imu.f_I[0], imu.w_I[2]]
    for odometry, exact in zip(estimate, seen["/estimator/odometry"], strict=True):
        assert exact.t == odometry.t and list(exact.q_wb) == list(odometry.q_WB)
        assert bool(exact.has_a_w) == (odometry.a_W is not None)
        if odometry.a_W is not None:
            assert list(exact.a_w) == list(odometry.a_W)
    for user, exact in zip(fixed, seen["/user/fixed"], strict=True):
        assert (exact.k, exact.ok) == (user.k, user.ok)
        assert list(exact.r_wb) == list(user.R_WB.ravel()) and list(exact.ids) == list(user.ids)


def _cloud_points(msg) -> np.ndarray:
    """A PointCloud2's points as a structured array, from its own fields (not cufund's code)."""
    numpy_of = {2: "u1", 6: "u4", 7: "<f4", 8: "<f8"}
    dtype = np.dtype(
        {
            "names": [f.name for f in msg.fields],
            "formats": [numpy_of[f.datatype] for f in msg.fields],
            "offsets": [f.offset for f in msg.fields],
            "itemsize": msg.point_step,
        }
    )
    assert not msg.is_bigendian and msg.row_step == msg.point_step * msg.width and msg.height == 1
    return np.frombuffer(bytes(msg.data), dtype)


def test_clouds_images_and_fixes_are_the_standard_ros2_messages(log_file):
    path, written = log_file
    seen = _decoded(path)
    clouds = [m for t, m, *_ in written if t == "/sensors/lidar"]
    truth = [m for t, m, *_ in written if t == "/truth/point_cloud"]
    for cloud, msg in zip(clouds, seen["/sensors/lidar"], strict=True):
        assert msg.header.frame_id == "lidar" and msg.width == len(cloud)
        assert [f.name for f in msg.fields] == ["x", "y", "z", "intensity", "tag", "line", "timestamp"]  # livox
        points = _cloud_points(msg)
        assert msg.point_step == 26 and points.dtype["timestamp"] == np.float64
        assert np.array_equal(np.stack([points["x"], points["y"], points["z"]], 1), cloud.points_L)
        assert np.array_equal(points["intensity"], np.round(cloud.intensity * 255).astype(np.float32))  # 0-255
        assert np.array_equal(points["line"], cloud.channel)
        stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
        assert stamp == round(cloud.t * 1e9)
        assert np.array_equal(points["timestamp"], stamp + np.round(cloud.dt * 1e9))  # whole ns
    for cloud, msg in zip(truth, seen["/truth/point_cloud"], strict=True):
        points = _cloud_points(msg)
        assert msg.header.frame_id == "world" and np.array_equal(points["object_id"], cloud.object_ids)
    images = [m for t, m, *_ in written if t == "/sensors/rgb_image"]
    for image, msg in zip(images, seen["/sensors/rgb_image"], strict=True):
        assert (msg.width, msg.height, msg.encoding, msg.step) == (8, 6, "rgb8", 24)
        assert bytes(msg.data) == image.image.tobytes() and msg.header.frame_id == "rgb_image"
    depth = [m for t, m, *_ in written if t == "/sensors/depth_image"]
    for image, msg in zip(depth, seen["/sensors/depth_image"], strict=True):
        assert msg.encoding == "32FC1" and bytes(msg.data) == image.image.astype("<f4").tobytes()
    fixes = [m for t, m, *_ in written if t == "/sensors/gps"]
    for fix, msg in zip(fixes, seen["/sensors/gps/ros"], strict=True):
        assert msg.header.frame_id == "gps"
        assert np.array_equal([msg.latitude, msg.longitude], [fix.latitude_deg, fix.longitude_deg], equal_nan=True)


def test_rosbags_deserialiser_agrees_with_the_bytes(log_file):
    """An independent CDR implementation (rosbags, from the same ros2msg text) decodes every standard message and
    serialises it back to the very bytes in the file (alignment, string lengths, sequence counts all as ROS 2 does)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    path, _ = log_file
    store = get_typestore(Stores.EMPTY)
    checked = set()
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, _channel, message in reader.iter_messages(log_time_order=False):
            if schema.encoding != "ros2msg" or schema.name.startswith("cufund_msgs/"):
                continue
            if schema.name not in checked:
                types = {}
                for i, part in enumerate(schema.data.decode().split("=" * 80 + "\n")):
                    if i == 0:
                        types.update(get_types_from_msg(part, schema.name))
                    else:
                        name, text = part.split("\n", 1)
                        types.update(get_types_from_msg(text, name.removeprefix("MSG: ").replace("/", "/msg/", 1)))
                store.register(types)
                checked.add(schema.name)
            msg = store.deserialize_cdr(message.data, schema.name)
            assert bytes(store.serialize_cdr(msg, schema.name)) == bytes(message.data), schema.name  # same bytes
            if schema.name == "sensor_msgs/msg/PointCloud2":
                assert msg.width == len(msg.data) // msg.point_step
            if schema.name == "tf2_msgs/msg/TFMessage":
                assert len(msg.transforms) >= 1 and msg.transforms[0].header.frame_id in ("world", "odom")
    assert {
        "sensor_msgs/msg/PointCloud2",
        "tf2_msgs/msg/TFMessage",
        "nav_msgs/msg/Odometry",
        "sensor_msgs/msg/Imu",
        "sensor_msgs/msg/Image",
        "sensor_msgs/msg/NavSatFix",
        "rosgraph_msgs/msg/Clock",
    } <= checked


def test_memory_stays_bounded_while_a_long_log_is_written(tmp_path):
    """10 000 odometry messages (3.3 MB of CDR): the logger holds one block, the rest is on disk."""
    rng = np.random.default_rng(0)
    arrays = rng.normal(size=(6, 3))
    path = tmp_path / "long.mcap"
    log = McapLogger(path, block_messages=256, compression="")
    tracemalloc.start()
    base, _ = tracemalloc.get_traced_memory()
    sizes = []
    for k in range(10_000):
        log.write(
            "/truth/odometry",
            M.Odometry(k * 1e-3, *arrays[:2], np.array([1.0, 0, 0, 0]), *arrays[2:5]),
            k * 1_000_000,
            k * 1_000_000,
        )
        if k % 2500 == 2499:
            sizes.append(path.stat().st_size)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert log.pending("/truth/odometry") < 256
    log.close()
    assert peak - base < 1_500_000, peak - base
    assert sizes[0] > 0.15 * sizes[-1] > 0 and sizes == sorted(sizes)  # streamed to disk as it goes
    assert sum(1 for _ in read_mcap(path)) == 10_000


def test_wrong_type_bad_time_and_changed_shape_are_errors(tmp_path):
    with McapLogger(tmp_path / "a.mcap") as log:
        log.write("/actuator/command", M.ActuatorCommand(0.0, np.ones(4)), 0, 0)
        with pytest.raises(TypeError, match="/actuator/command.*ActuatorCommand.*Imu"):
            log.write("/actuator/command", M.Imu(0.0, np.ones(3), np.ones(3)), 0, 0)
        with pytest.raises(ValueError, match="absolute name"):
            log.write("relative", M.Imu(0.0, np.ones(3), np.ones(3)), 0, 0)
    with pytest.raises(ValueError, match="closed McapLogger"):
        log.write("/actuator/command", M.ActuatorCommand(0.0, np.ones(4)), 1, 1)
    with McapLogger(tmp_path / "b.mcap") as log:  # each error at the write that makes it
        log.write("/actuator/command", M.ActuatorCommand(0.0, np.ones(4)), 0, 0)
        with pytest.raises(ValueError, match="rotor_speeds.*shape"):
            log.write("/actuator/command", M.ActuatorCommand(0.0, np.ones(6)), 1, 1)
        with pytest.raises(TypeError, match="log_time_ns must be non-negative integer"):
            log.write("/actuator/command", M.ActuatorCommand(0.0, np.ones(4)), 0.5, 0)
        with pytest.raises(TypeError, match="publish_time_ns must be non-negative integer"):
            log.write("/actuator/command", M.ActuatorCommand(0.0, np.ones(4)), 2, -1)
        log.write("/actuator/command", M.ActuatorCommand(0.1, np.ones(4)), 3, 3)
        log.write("/actuator/command", M.ActuatorCommand(0.2, np.ones(4)), 2**64 - 1, 2**63)  # checked path
    assert [(r.log_time_ns, r.publish_time_ns) for r in read_mcap(tmp_path / "b.mcap")] == [
        (0, 0),
        (3, 3),
        (2**64 - 1, 2**63),
    ]  # the bad ones were not logged
    with pytest.raises(TypeError, match="cannot log a value of type object"):
        with McapLogger(tmp_path / "d.mcap") as log:
            log.write("/x", UserMessage(0.0, "", Color.RED, Inner(1.0, ""), np.zeros(1), (), {"k": object()}), 0, 0)


def test_int_arrays_in_a_float_topic_take_the_checked_path(tmp_path):
    """Same byte size, other dtype: never reinterpreted, logged as the first message's dtype (value-exact)."""
    path = tmp_path / "a.mcap"
    with McapLogger(path) as log:
        log.write("/a", M.ActuatorCommand(0.0, np.array([1.5, 2, 3, 4])), 0, 0)
        log.write("/a", M.ActuatorCommand(0.1, np.array([7, 8, 9, 2**40])), 1, 1)
    second = list(read_mcap(path))[1].message
    assert second.rotor_speeds.dtype == np.float64 and second.rotor_speeds.tolist() == [7, 8, 9, 2**40]


@pytest.mark.parametrize("damage", ["flipped", "not_mcap", "empty", "missing"])  # truncated: tests/security
def test_a_damaged_file_gives_a_clear_error(log_file, tmp_path, damage):
    path, _ = log_file
    data = bytearray(path.read_bytes())
    bad = tmp_path / "bad.mcap"
    if damage == "truncated":
        bad.write_bytes(data[: len(data) // 2])
    elif damage == "flipped":
        with open(path, "rb") as f:
            index = make_reader(f).get_summary().chunk_indexes[3]
        at = index.chunk_start_offset + index.chunk_length - 10  # inside the compressed records
        data[at] ^= 0xFF
        bad.write_bytes(data)
    elif damage == "not_mcap":
        bad.write_text("t,x\n0,1\n" * 100)
    elif damage == "empty":
        bad.write_bytes(b"")
    with pytest.raises(McapReadError, match="bad.mcap"):
        list(read_mcap(bad))


def test_an_unclosed_logger_leaves_a_file_without_summary(tmp_path):
    path = tmp_path / "open.mcap"
    log = McapLogger(path, block_messages=2)
    for k in range(5):
        log.write("/a", M.ActuatorCommand(k * 0.1, np.ones(4)), k, k)
    del log
    with pytest.warns(TruncatedLogWarning, match="no summary"):  # read up to its last complete chunk
        assert [r.log_time_ns for r in read_mcap(path)] == [0, 1, 2, 3]


@pytest.mark.parametrize("tail", [b"", b"\x00" * 4096, b"\xff" * 100])
def test_a_log_cut_short_reads_to_its_last_complete_record(tmp_path, tail):
    """A log cut in the middle (a killed run) reads up to its last complete chunk, whatever follows the cut: nothing,
    the zero-filled blocks a power loss leaves on ext4 or xfs, or garbage."""
    whole = tmp_path / "whole.mcap"
    log = McapLogger(whole, block_messages=10)
    for k in range(200):
        log.write("/a", M.ActuatorCommand(k * 0.1, np.ones(4)), k, k)
    log.close()
    data = whole.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2] + tail)
    with pytest.warns(TruncatedLogWarning):
        times = [r.log_time_ns for r in read_mcap(cut)]
    assert times and times == list(range(len(times))) and len(times) % 10 == 0 and len(times) < 200


@pytest.mark.filterwarnings("ignore:This process .* is multi-threaded:DeprecationWarning")  # Python >= 3.12
def test_a_forked_child_cannot_write_through_its_parents_logger(tmp_path):
    """The child has the logger's queue but not its writer thread: it must fail at once, not wait forever. Run in a
    fresh interpreter: this process may hold threads of other libraries (JAX) that make a fork unsafe."""
    import subprocess
    import sys

    script = f"""
import multiprocessing
import numpy as np
from cufund.core import messages as M
from cufund.logs import McapLogger, read_mcap

LOG = McapLogger({str(tmp_path / "a.mcap")!r}, block_messages=1)

def write_in_child():
    try:
        LOG.write("/a", M.ActuatorCommand(1.0, np.ones(4)), 2, 2)
    except RuntimeError as exc:
        return str(exc)
    return "no error"

if __name__ == "__main__":
    LOG.write("/a", M.ActuatorCommand(0.0, np.ones(4)), 0, 0)
    with multiprocessing.get_context("fork").Pool(1) as pool:
        message = pool.apply(write_in_child)
    assert "forked child" in message, message
    LOG.write("/a", M.ActuatorCommand(0.1, np.ones(4)), 1, 1)  # the parent goes on
    LOG.close()
    print([r.log_time_ns for r in read_mcap({str(tmp_path / "a.mcap")!r})])
"""
    path = tmp_path / "fork_child.py"
    path.write_text(script)
    out = subprocess.run([sys.executable, str(path)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[0, 1]"


def test_variable_length_messages_are_logged_as_json_and_round_trip(tmp_path):
    """A tunnel estimate grows a row per frame found and a diagnostics message has a row per weak direction: such
    messages (``variable_length``) get the JSON codec, so a later message of another size is no error."""
    estimates = [
        M.TunnelEstimate(
            0.1 * k, np.full((k, 3), k * 0.5), np.tile([1.0, 0, 0], (k, 1)), np.ones((k, 2)), np.linspace(0, 1, k), k
        )
        for k in range(1, 5)
    ]
    diagnostics = [
        M.OdometryDiagnostics(0.1 * k, 10, 5, 3, np.arange(6.0), np.ones((k % 2, 6)), 1.0, 1.0, "") for k in range(4)
    ]
    with McapLogger(tmp_path / "a.mcap") as log:
        for k, (e, d) in enumerate(zip(estimates, diagnostics, strict=True)):
            log.write("/perception/tunnel", e, k, k)
            log.write("/estimator/diagnostics", d, k, k)
    records = list(read_mcap(tmp_path / "a.mcap"))
    back = {
        topic: [r.message for r in records if r.topic == topic]
        for topic in ("/perception/tunnel", "/estimator/diagnostics")
    }
    for sent, got in ((estimates, back["/perception/tunnel"]), (diagnostics, back["/estimator/diagnostics"])):
        assert len(got) == len(sent)
        for a, b in zip(sent, got, strict=True):
            for f in dataclasses.fields(a):
                x, y = getattr(a, f.name), getattr(b, f.name)
                assert np.array_equal(x, y) if isinstance(x, np.ndarray) else x == y, f.name


def test_the_same_messages_give_the_same_file_byte_for_byte(tmp_path):
    """Determinism: the writer thread changes when a chunk is written, never what or where; in the caller's
    thread (background=False) the file is the same too."""
    stream = _stream(np.random.default_rng(11))
    files = []
    for k, background in enumerate((True, True, False)):
        path = tmp_path / f"{k}.mcap"
        _write(path, stream, block_messages=3, background=background)
        files.append(path.read_bytes())
    assert files[0] == files[1] == files[2]
    assert len(list(read_mcap(tmp_path / "0.mcap"))) == len(stream)


@pytest.mark.skipif(not __import__("os").path.exists("/dev/full"), reason="needs /dev/full")
def test_a_failed_disk_write_is_an_oserror_never_silent():
    """/dev/full fails every write with ENOSPC: the writer thread's error reaches the caller (at a later write or
    at close), and close still ends the writer thread and releases the file."""
    import contextlib

    log = McapLogger("/dev/full", block_messages=1)
    with pytest.raises(OSError, match="writing the log failed"):
        for k in range(100):
            log.write("/a", M.ActuatorCommand(k * 0.1, np.ones(4)), k, k)
        log.close()
    with contextlib.suppress(OSError):  # the summary cannot be written either
        log.close()
    assert log._closed
    log.close()  # and then idempotent


@pytest.mark.skipif(
    not (__import__("os").path.exists("/dev/full") and __import__("os").path.isdir("/proc/self/fd")),
    reason="needs /dev/full and /proc",
)
@pytest.mark.parametrize("background", [True, False])
def test_a_write_error_stays_reported_by_every_later_write_and_close(tmp_path, background):
    """Once the writer has reported a write error it reports it again at every later write and at close, and writes
    nothing more (the file's offsets would be wrong). The logger's descriptor is pointed (dup2) at /dev/full until
    a write fails, then at a working file, which must stay empty."""
    import os

    def point_at(fd: int, target: str | os.PathLike[str]) -> None:
        other = os.open(target, os.O_WRONLY | os.O_CREAT)
        os.dup2(other, fd)
        os.close(other)

    path = tmp_path / "run.mcap"
    log = McapLogger(path, block_messages=1, background=background)
    fds = [int(n) for n in os.listdir("/proc/self/fd") if _link(f"/proc/self/fd/{n}") == str(path)]
    assert len(fds) == 1
    point_at(fds[0], "/dev/full")
    with pytest.raises(OSError, match="writing the log failed"):
        for k in range(100):
            log.write("/a", M.ActuatorCommand(k * 0.1, np.ones(4)), k, k)
    point_at(fds[0], tmp_path / "after.bin")  # the "disk" recovers
    for k in range(5):
        with pytest.raises(OSError, match="writing the log failed"):
            log.write("/a", M.ActuatorCommand(k * 0.1, np.ones(4)), k, k)
    with pytest.raises(OSError, match="writing the log failed"):
        log.close()
    assert log._closed
    assert os.path.getsize(tmp_path / "after.bin") == 0


def _link(path: str) -> str | None:
    try:
        return __import__("os").readlink(path)
    except OSError:  # the listing's own descriptor, closed by now
        return None


class _Line:
    """A trajectory along x at 2 m/s from t_start for 1.5 s, yawing at 0.4 rad/s (the planning protocol)."""

    t_start, duration = 3.0, 1.5

    def sample(self, t):
        from cufund.planning.trajectory import TrajectorySamples

        t = np.atleast_1d(np.asarray(t, float))
        s = t - self.t_start
        z = np.zeros((len(t), 3))
        p = np.column_stack([2.0 * s, np.zeros_like(s), np.ones_like(s)])
        return TrajectorySamples(t, p, z, z, z, 0.4 * s, np.full_like(s, 0.4))


def test_planned_trajectories_are_logged_as_nav_msgs_paths_and_not_read_back(tmp_path):
    path = tmp_path / "path.mcap"
    with McapLogger(path) as log:
        log.write("/planner/trajectory", M.TrajectoryUpdate(2.5, _Line()), 2_500_000_000, 2_500_000_000)
        log.write("/sensors/imu", M.Imu(2.5, np.zeros(3), np.zeros(3)), 2_500_000_000, 2_500_000_000)
    (msg,) = _decoded(path)["/planner/trajectory"]
    assert msg.header.frame_id == "world" and msg.header.stamp.sec == 2 and len(msg.poses) == 16  # every 0.1 s
    for k, pose in enumerate(msg.poses):
        t = 3.0 + 0.1 * k
        assert pose.header.stamp.sec + pose.header.stamp.nanosec * 1e-9 == pytest.approx(t, abs=1e-9)
        assert [pose.pose.position.x, pose.pose.position.z] == pytest.approx([2.0 * 0.1 * k, 1.0], abs=1e-12)
        o = pose.pose.orientation
        assert 2 * np.arctan2(o.z, o.w) == pytest.approx(0.4 * 0.1 * k, abs=1e-12) and o.x == o.y == 0.0
    assert list(log_topics(path)) == ["/sensors/imu"]  # a path is for viewers: read_mcap does not rebuild it
    assert [r.topic for r in read_mcap(path)] == ["/sensors/imu"]


def test_a_log_with_a_codec_this_cufund_does_not_know_is_refused_naming_it(tmp_path, monkeypatch):
    import cufund.logs.mcap_writer as writer
    from cufund.logs import codecs

    class Future(codecs.JsonCodec):
        name = "ros3.Fancy"

    monkeypatch.setattr(writer, "codec_for", lambda topic, message: Future(type(message)))
    path = tmp_path / "future.mcap"
    with McapLogger(path) as log:
        log.write("/mission/state", M.MissionState(0.0, "takeoff", "", 0), 0, 0)
    with pytest.raises(McapReadError, match=r"unknown cufund codec 'ros3.Fancy' \(a log of a newer cufund\?"):
        read_mcap(path)
