"""ROS 2 interop against an independent implementation: eProsima Fast DDS (ROS 2's default middleware) in a C++
peer built here from ROS 2's IDL by fastddsgen (tests/apps/ros2/fastdds), against cufund's Cyclone DDS side.

- The peer's XML profile keeps it on loopback (checked from its configuration and from its sockets).
- Cyclone DDS -> Fast DDS: the peer receives cufund's Imu, PointCloud2 and TFMessage with ROS 2's type names, its
  fastddsgen types decode them, and the payload bytes it received equal ``rosbags``' CDR serialisation of the same
  messages (rosbags builds them from the values, not from cufund's bytes).
- Fast DDS -> Cyclone DDS: the peer's Imu (serialised by Fast CDR) decodes on cufund's side with its values.
- The bridge: a run's /imu, /points and /tf reach the peer with the run's values and bytes; the peer's PoseStamped
  goal on /goal_pose flies the simulated vehicle there.

Nothing here is checked against a live ROS 2 (none can be installed here); the wire contract is checked against
two DDS implementations and rosbags' CDR.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("cyclonedds")
pytest.importorskip("rosbags")

HERE = Path(__file__).resolve().parent / "fastdds"
PROFILE = HERE / "loopback_profile.xml"
BUILD = Path(__file__).resolve().parents[3] / "build" / "fastdds-peer"
NS = 1_000_000_000


def _domain(offset: int) -> int:
    """A DDS domain of this test process (150..229: apart from the bridge tests' and domain 0)."""
    return 150 + (os.getpid() * 5 + offset) % 80


def _unavailable(reason: str) -> None:
    if os.environ.get("CI"):  # CI installs the Debian packages (make deps): their absence is a failure there
        pytest.fail(reason)
    pytest.skip(reason)


@pytest.fixture(scope="session")
def peer() -> Path:
    """The Fast DDS peer, built with cmake in the checkout's (git-ignored) build/fastdds-peer: configured once, then
    each session's build redoes only what changed (a no-op when nothing did), so no stale copies pile up and no
    binary is taken from a folder anyone could have made under /tmp."""
    if shutil.which("fastddsgen") is None:
        _unavailable("fastddsgen is not installed (make deps installs fastddsgen, libfastrtps-dev, libfastcdr-dev)")
    cmake = shutil.which("cmake", path=f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}")
    if cmake is None:
        _unavailable("cmake is not installed")
    BUILD.mkdir(parents=True, exist_ok=True)
    with open(BUILD / "lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # one build for concurrent test processes
        log = BUILD / "build.log"
        with open(log, "w") as out:
            gen = ["-G", "Ninja"] if shutil.which("ninja", path=f"{Path(cmake).parent}:/usr/bin") else []
            cache = BUILD / "CMakeCache.txt"
            if not (cache.exists() and f"CMAKE_HOME_DIRECTORY:INTERNAL={HERE}\n" in cache.read_text()):
                cache.unlink(missing_ok=True)  # not configured yet, or from the sources of a checkout since moved
                shutil.rmtree(BUILD / "CMakeFiles", ignore_errors=True)
                if subprocess.run([cmake, "-S", HERE, "-B", BUILD, *gen], stdout=out, stderr=out).returncode:
                    cache.unlink(missing_ok=True)
                    _unavailable(
                        f"the Fast DDS peer's packages were not found by cmake (Fast DDS dev packages?): {log}"
                    )
            built = subprocess.run([cmake, "--build", BUILD, "-j", "2"], stdout=out, stderr=out).returncode == 0
        if not built:  # its packages are there: a compile error in the peer is a failure, not a skip
            pytest.fail(f"the Fast DDS peer did not build: {log}:\n{log.read_text()[-3000:]}")
    return BUILD / "peer"


class Peer:
    """A running peer: its JSON lines as they come."""

    def __init__(self, binary: Path, domain: int, *args: str, cwd: Path):
        env = {k: v for k, v in os.environ.items() if "PROFILES_FILE" not in k}  # only our profile applies
        self.stderr = cwd / f"peer-{domain}-{args[0]}.stderr"
        with open(self.stderr, "w") as err:
            self.proc = subprocess.Popen(
                [str(binary), str(PROFILE), str(domain), *args],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=err,
                text=True,
                cwd=cwd,  # Fast DDS also loads DEFAULT_FASTRTPS_PROFILES.xml from its working directory: none there
                env=env,
            )
        self.lines: list[dict] = []
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        with self.proc.stdout:
            for line in self.proc.stdout:
                with self._cond:
                    self.lines.append(json.loads(line))
                    self._cond.notify_all()

    def wait_for(self, event: str, timeout: float = 20.0, count: int = 1) -> list[dict]:
        end = time.monotonic() + timeout
        with self._cond:
            while len(found := [x for x in self.lines if x["event"] == event]) < count:
                left = end - time.monotonic()
                if left <= 0 or self.proc.poll() is not None and not self._thread.is_alive():
                    raise AssertionError(f"peer: no {count} '{event}' line(s) in {timeout} s: {self.lines[-5:]}")
                self._cond.wait(min(left, 0.1))
            return found

    def finish(self, timeout: float = 60.0) -> int:
        code = self.proc.wait(timeout=timeout)
        self._thread.join(timeout=5)
        return code

    def samples(self, topic: str) -> list[dict]:
        return [x for x in self.lines if x["event"] == "sample" and x["topic"] == topic]

    def send(self, line: str) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(line + "\n")
        self.proc.stdin.flush()

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        if self.proc.stdin is not None:
            self.proc.stdin.close()
        self.proc.wait(timeout=10)
        self._thread.join(timeout=5)


@contextlib.contextmanager
def running(binary: Path, domain: int, *args: str, cwd: Path):
    p = Peer(binary, domain, *args, cwd=cwd)
    try:
        yield p
    finally:
        p.stop()


def unpadded(payload: bytes) -> bytes:
    """A DDS payload without the padding a writer may add to reach a whole 4-byte word (XCDR: its count is in the
    encapsulation options' last two bits)."""
    pad = payload[3] & 3
    assert payload[len(payload) - pad :] == b"\0" * pad
    body = payload[: len(payload) - pad]
    return body[:3] + bytes([body[3] & ~3 & 0xFF]) + body[4:]


def _typestore():
    from cufund.logs.rosbag2_reader import rosbags_typestore

    return rosbags_typestore()


def _header(store, ns: int, frame: str):
    T = store.types
    return T["std_msgs/msg/Header"](
        stamp=T["builtin_interfaces/msg/Time"](sec=ns // NS, nanosec=ns % NS), frame_id=frame
    )


def rosbags_imu(store, ns: int, frame: str, w, f) -> bytes:
    """``sensor_msgs/msg/Imu`` without orientation (REP 145: covariance[0] -1) serialised by rosbags."""
    T = store.types
    V = T["geometry_msgs/msg/Vector3"]
    cov = np.zeros(9)
    unknown = cov.copy()
    unknown[0] = -1.0
    msg = T["sensor_msgs/msg/Imu"](
        header=_header(store, ns, frame),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=0.0),
        orientation_covariance=unknown,
        angular_velocity=V(x=float(w[0]), y=float(w[1]), z=float(w[2])),
        angular_velocity_covariance=cov,
        linear_acceleration=V(x=float(f[0]), y=float(f[1]), z=float(f[2])),
        linear_acceleration_covariance=cov,
    )
    return bytes(store.serialize_cdr(msg, "sensor_msgs/msg/Imu"))


LIVOX = [("x", "<f4", 7), ("y", "<f4", 7), ("z", "<f4", 7), ("intensity", "<f4", 7), ("tag", "u1", 2),
         ("line", "u1", 2), ("timestamp", "<f8", 8)]  # fmt: skip
"""livox_ros_driver2's point (LivoxPointXyzrtlt, packed): name, numpy type, PointField datatype."""


def rosbags_livox_cloud(store, cloud, frame: str) -> bytes:
    """A cufund PointCloud as livox_ros_driver2 publishes it, built field by field and serialised by rosbags."""
    T = store.types
    dtype = np.dtype([(n, t) for n, t, _ in LIVOX])  # packed: 26 bytes
    ns = round(cloud.t * NS)
    data = np.zeros(len(cloud.dt), dtype)
    for i, k in enumerate("xyz"):
        data[k] = cloud.points_L[:, i]
    data["intensity"] = np.round(np.asarray(cloud.intensity) * 255.0)
    data["line"] = cloud.channel
    data["timestamp"] = ns + np.round(np.asarray(cloud.dt) * 1e9)
    fields = [
        T["sensor_msgs/msg/PointField"](name=n, offset=dtype.fields[n][1], datatype=d, count=1) for n, _, d in LIVOX
    ]
    msg = T["sensor_msgs/msg/PointCloud2"](
        header=_header(store, ns, frame),
        height=1,
        width=len(data),
        fields=fields,
        is_bigendian=False,
        point_step=dtype.itemsize,
        row_step=dtype.itemsize * len(data),
        data=np.frombuffer(data.tobytes(), np.uint8),
        is_dense=True,
    )
    return bytes(store.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2"))


def rosbags_tf(store, ns: int, parent: str, child: str, p, q_wxyz) -> bytes:
    T = store.types
    w, x, y, z = (float(v) for v in q_wxyz)
    ts = T["geometry_msgs/msg/TransformStamped"](
        header=_header(store, ns, parent),
        child_frame_id=child,
        transform=T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=float(p[0]), y=float(p[1]), z=float(p[2])),
            rotation=T["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
        ),
    )
    return bytes(store.serialize_cdr(T["tf2_msgs/msg/TFMessage"](transforms=[ts]), "tf2_msgs/msg/TFMessage"))


def _sockets(pid: int) -> dict[str, list[str]]:
    """The local addresses (hex ip:port as /proc/net shows them) of the UDP sockets of process ``pid``, by table."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        with contextlib.suppress(OSError):
            target = os.readlink(fd)
            if target.startswith("socket:["):
                inodes.add(target[8:-1])
    out: dict[str, list[str]] = {}
    for table in ("udp", "udp6"):
        rows = Path(f"/proc/{pid}/net/{table}").read_text().splitlines()[1:]
        out[table] = [r.split()[1] for r in rows if r.split()[9] in inodes]
    return out


def test_the_fastdds_profile_keeps_the_peer_on_loopback(peer, tmp_path):
    """The XML profile is applied (only its UDPv4 transport, whitelisted to 127.0.0.1; unicast locators and
    initial peers on 127.0.0.1; no multicast locator), and the peer's sockets are all bound to 127.0.0.1, none on
    the domain's multicast discovery port."""
    d = _domain(0)
    info = subprocess.run([str(peer), str(PROFILE), str(d), "info"], capture_output=True, text=True, cwd=tmp_path)
    assert info.returncode == 0, info.stderr
    conf = json.loads(info.stdout.splitlines()[0])
    assert conf["use_builtin_transports"] is False  # no shared memory, no default UDP on every interface
    assert conf["user_transports"] == [{"kind": "UDPv4", "interface_whitelist": ["127.0.0.1"]}]
    assert conf["metatraffic_multicast"] == [] and conf["default_multicast"] == []
    for key in ("metatraffic_unicast", "initial_peers", "default_unicast"):
        assert conf[key] and all(loc.startswith("UDPv4:[127.0.0.1]") for loc in conf[key]), conf[key]
    with running(peer, d, "sub", "30", "1", "rt/imu=imu", cwd=tmp_path) as p:
        p.wait_for("ready")
        time.sleep(0.5)  # its discovery announcements went out
        socks = _sockets(p.proc.pid)
    assert socks["udp6"] == []
    assert len(socks["udp"]) >= 2
    hosts = {s.split(":")[0] for s in socks["udp"]}
    assert hosts == {"0100007F"}, socks  # 127.0.0.1, little-endian hex: no socket on 0.0.0.0 or a multicast group
    ports = {int(s.split(":")[1], 16) for s in socks["udp"]}
    assert 7400 + 250 * d not in ports  # the SPDP multicast port of the domain
    assert any(7410 + 250 * d <= port < 7410 + 250 * d + 64 for port in ports)  # a metatraffic unicast port


def _cyclone(domain: int):
    from cufund.apps.ros2.dds import DdsParticipant

    return DdsParticipant(domain)


def _wait_matched(writers, timeout: float = 20.0) -> None:
    end = time.monotonic() + timeout
    while not all(w.matched() for w in writers):
        assert time.monotonic() < end, "the Fast DDS reader was not discovered"
        time.sleep(0.05)


def test_cyclone_to_fastdds_types_contents_and_bytes(peer, tmp_path):
    """cufund's Cyclone DDS writers -> the Fast DDS peer: ROS 2's type names, fastddsgen's types decode the
    values, and every payload received equals rosbags' serialisation of the same message."""
    from cufund.apps.ros2.dds import QosProfile
    from cufund.apps.ros2.encode import imu_encoder, point_cloud_encoder, tf
    from cufund.core.messages import Imu, PointCloud

    d = _domain(1)
    rng = np.random.default_rng(3)
    imus = [Imu(t=0.005 * k + 1.0, f_I=rng.normal(size=3), w_I=rng.normal(size=3)) for k in range(5)]
    n = 700  # a cloud of about 18 kB: fragmented on the wire
    clouds = []
    for k in range(3):
        xyz = rng.uniform(-20, 20, size=(n, 3)).astype(np.float32)
        clouds.append(
            PointCloud(
                t=1.0 + 0.1 * k,
                dt=np.sort(rng.uniform(0, 0.1, n)),
                points_L=xyz,
                ranges=np.linalg.norm(xyz.astype(float), axis=1),
                intensity=rng.uniform(0, 1, n),
                channel=rng.integers(0, 4, n),
                frame=k,
            )
        )
    poses = [(1.0 + 0.01 * k, rng.normal(size=3), np.array([0.5, 0.5, 0.5, 0.5])) for k in range(4)]
    dump = tmp_path / "dump"
    dump.mkdir()
    topics = ["rt/imu=imu,reliable", "rt/points=points,reliable", "rt/tf=tf,reliable"]  # none lost
    args = ["sub", "60", "100", "--dump", str(dump), "--idle", "2", *topics]
    with running(peer, d, *args, cwd=tmp_path) as p:
        p.wait_for("ready")
        dds = _cyclone(d)
        try:
            reliable = QosProfile(depth=100)
            w_imu = dds.writer("/imu", "sensor_msgs/msg/Imu", reliable)
            w_points = dds.writer("/points", "sensor_msgs/msg/PointCloud2", reliable)
            w_tf = dds.writer("/tf", "tf2_msgs/msg/TFMessage", reliable)
            _wait_matched([w_imu, w_points, w_tf])
            p.wait_for("matched", count=3)
            time.sleep(0.3)
            encode_imu, encode_cloud = imu_encoder("imu"), point_cloud_encoder("lidar")
            for m in imus:
                w_imu.write(encode_imu(m))
                time.sleep(0.02)
            for c in clouds:
                w_points.write(encode_cloud(c))
                time.sleep(0.05)
            for t, pos, q in poses:
                w_tf.write(tf(t, [("world", "base_link", pos, q)]))
                time.sleep(0.02)
            assert p.finish() == 0
        finally:
            dds.close()
    store = _typestore()
    got_imu, got_points, got_tf = p.samples("rt/imu"), p.samples("rt/points"), p.samples("rt/tf")
    assert len(got_imu) == len(imus) and len(got_points) == len(clouds) and len(got_tf) == len(poses)
    assert {s["type"] for s in got_imu} == {"sensor_msgs::msg::dds_::Imu_"}
    assert {s["type"] for s in got_points} == {"sensor_msgs::msg::dds_::PointCloud2_"}
    assert {s["type"] for s in got_tf} == {"tf2_msgs::msg::dds_::TFMessage_"}
    for s, m in zip(got_imu, imus, strict=True):
        ns = round(m.t * NS)
        assert s["decoded"] and (s["sec"], s["nanosec"], s["frame_id"]) == (ns // NS, ns % NS, "imu")
        assert s["angular_velocity"] == m.w_I.tolist() and s["linear_acceleration"] == m.f_I.tolist()
        assert s["orientation_covariance0"] == -1.0
        assert unpadded(Path(s["file"]).read_bytes()) == rosbags_imu(store, ns, "imu", m.w_I, m.f_I)
    for s, c in zip(got_points, clouds, strict=True):
        assert s["decoded"] and s["frame_id"] == "lidar" and (s["height"], s["width"]) == (1, n)
        assert s["fields"] == [
            [name, off, dt, 1] for (name, _, dt), off in zip(LIVOX, (0, 4, 8, 12, 16, 17, 18), strict=True)
        ]
        assert s["point_step"] == 26 and s["row_step"] == 26 * n and s["data_bytes"] == 26 * n
        assert s["first_point"] == c.points_L[0].astype(float).tolist()
        assert unpadded(Path(s["file"]).read_bytes()) == rosbags_livox_cloud(store, c, "lidar")
    for s, (t, pos, q) in zip(got_tf, poses, strict=True):
        (tr,) = s["transforms"]
        assert (tr["frame_id"], tr["child_frame_id"]) == ("world", "base_link")
        assert tr["translation"] == pos.tolist() and tr["rotation"] == [0.5, 0.5, 0.5, 0.5]
        ns = round(t * NS)
        assert unpadded(Path(s["file"]).read_bytes()) == rosbags_tf(store, ns, "world", "base_link", pos, q)


def test_fastdds_to_cyclone(peer, tmp_path):
    """The Fast DDS peer's Imu (Fast CDR's serialisation) is read by cufund's Cyclone DDS side with its values."""
    from cufund.apps.ros2.dds import QosProfile

    d = _domain(2)
    dds = _cyclone(d)
    try:
        reader = dds.reader("/imu", "sensor_msgs/msg/Imu", QosProfile(depth=100))
        got: list = []
        with running(peer, d, "pub", "30", "5", "rt/imu=imu", cwd=tmp_path) as p:
            end = time.monotonic() + 40
            while len(got) < 5 and time.monotonic() < end:
                got += reader.take(N=10)
                time.sleep(0.02)
            assert p.finish() == 0
            assert p.wait_for("ready")[0]["type"] == "sensor_msgs::msg::dds_::Imu_"
    finally:
        dds.close()
    assert [m.header.stamp.sec for m in got] == [0, 1, 2, 3, 4]
    for k, m in enumerate(got):
        assert m.header.frame_id == "imu_link"
        w, f = m.angular_velocity, m.linear_acceleration
        assert [w.x, w.y, w.z] == [0.1 * k, 0.2, 0.3] and [f.x, f.y, f.z] == [1.0, 2.0, 9.81]
        assert m.orientation_covariance[0] == -1.0


def _scenario(name: str, ros2: dict, **changes):
    from cufund.scenarios.schema import ScenarioConfig, load_scenario

    cfg = load_scenario(name)
    data = cfg.to_dict()
    data.update(changes)
    data["ros2"] = ros2
    return ScenarioConfig.from_dict(data, cfg.base_dir)


def test_the_bridge_reaches_fastdds(peer, tmp_path):
    """A run with the bridge (real time, nothing in lockstep, the peer matched first): the Fast DDS peer receives /imu, /points (the
    LiDAR mapped there) and /tf, each sample the run's message at its stamp, value for value and, for the IMU and
    the LiDAR, byte for byte as rosbags serialises them."""
    from cufund.logs import McapLogger, read_mcap
    from cufund.scenarios.build import build_simulation, run_built

    d = _domain(3)
    cfg = _scenario(
        "square_lio",
        {"domain_id": d, "realtime": True, "topics": {"/sensors/lidar": "/points"}},
        duration=3.0,
    )
    dump = tmp_path / "dump"
    dump.mkdir()
    args = ["sub", "60", "1000000", "--dump", str(dump), "--idle", "2", "rt/imu=imu", "rt/points=points", "rt/tf=tf"]
    with running(peer, d, *args, cwd=tmp_path) as p:
        p.wait_for("ready")
        with McapLogger(tmp_path / "run.mcap") as log:
            built = build_simulation(cfg, logger=log)
            (bridge,) = [c for c in built.simulator.components if c.name == "ros2_bridge"]
            bridge.reset()  # its participant and writers now (the run's reset keeps them), so the peer
            p.wait_for("matched", count=3, timeout=30)  # matches them before the first sample goes out
            _wait_matched([bridge._writers[name] for name in ("/imu", "/points", "/tf")])  # and they match it
            run_built(built)
        assert p.finish() == 0
    imu = {round(r.message.t * NS): r.message for r in read_mcap(tmp_path / "run.mcap", topics=["/sensors/imu"])}
    clouds = {round(r.message.t * NS): r.message for r in read_mcap(tmp_path / "run.mcap", topics=["/sensors/lidar"])}
    truth = {round(r.message.t * NS): r.message for r in read_mcap(tmp_path / "run.mcap", topics=["/truth/odometry"])}
    store = _typestore()
    got_imu, got_points, got_tf = p.samples("rt/imu"), p.samples("rt/points"), p.samples("rt/tf")
    print(f"received {len(got_imu)}/{len(imu)} IMU, {len(got_points)}/{len(clouds)} clouds, {len(got_tf)} tf")
    # matched before the run, paced to real time: every IMU sample but what best effort may drop on a loaded host
    assert len(got_imu) > 0.9 * len(imu) and len(got_points) > 0.9 * len(clouds) and len(got_tf) > 500
    assert {s["type"] for s in got_imu} == {"sensor_msgs::msg::dds_::Imu_"}
    assert {s["type"] for s in got_points} == {"sensor_msgs::msg::dds_::PointCloud2_"}
    assert {s["type"] for s in got_tf} == {"tf2_msgs::msg::dds_::TFMessage_"}
    for s in got_imu:
        ns = s["sec"] * NS + s["nanosec"]
        m = imu[ns]
        assert s["angular_velocity"] == m.w_I.tolist() and s["linear_acceleration"] == m.f_I.tolist()
        assert unpadded(Path(s["file"]).read_bytes()) == rosbags_imu(store, ns, s["frame_id"], m.w_I, m.f_I)
    for s in got_points:
        c = clouds[s["sec"] * NS + s["nanosec"]]
        assert s["width"] == len(c.dt) and s["first_point"] == c.points_L[0].astype(float).tolist()
        assert unpadded(Path(s["file"]).read_bytes()) == rosbags_livox_cloud(store, c, s["frame_id"])
    seen_truth = 0
    for s in got_tf:
        for tr in s["transforms"]:
            if tr["child_frame_id"] == "base_link_truth":
                m = truth[tr["sec"] * NS + tr["nanosec"]]
                assert tr["frame_id"] == "world" and tr["translation"] == m.p_W.tolist()
                w, x, y, z = m.q_WB.tolist()
                assert tr["rotation"] == [x, y, z, w]
                seen_truth += 1
    assert seen_truth > 100


def test_a_fastdds_goal_flies_the_vehicle(peer, tmp_path):
    """The Fast DDS peer's PoseStamped on /goal_pose (what RViz's goal tool sends) is taken by the bridge: the
    vehicle takes off and flies there. The goal is volatile, as RViz's: it is sent once the bridge's reader and the
    peer's writer have matched each other."""
    from cufund.scenarios.build import build_simulation, run_built

    d = _domain(4)
    goal = (-1.0, 1.0, 1.2)
    cfg = _scenario(
        "vehicle",
        {"domain_id": d, "realtime": True, "rate_hz": 50.0},
        duration=12.0,
        planner={"kind": "commander", "takeoff_altitude": 1.2},
    )
    built = build_simulation(cfg)
    (bridge,) = [c for c in built.simulator.components if c.name == "ros2_bridge"]
    bridge.reset()  # its participant and readers now (the run's reset keeps them)
    args = ["pub", "60", "1", "rt/goal_pose=pose", *(str(v) for v in goal), "--go-on-stdin"]
    with running(peer, d, *args, cwd=tmp_path) as p:
        p.wait_for("waiting", timeout=30)
        end = time.monotonic() + 30
        while not bridge._readers["goal"].get_matched_publications():
            assert time.monotonic() < end, "the bridge's /goal_pose reader did not match the peer's writer"
            time.sleep(0.05)
        runs: list = []
        flight = threading.Thread(target=lambda: runs.append(run_built(built)))
        flight.start()  # real time; the run's start drains what the bridge's readers held before it
        while bridge.stats.get("steps", 0) < 5 and flight.is_alive():
            time.sleep(0.01)
        p.send("go")
        p.wait_for("sent")
        flight.join(timeout=120)
        assert p.finish() == 0
    (run,) = runs
    assert p.wait_for("ready")[0]["type"] == "geometry_msgs::msg::dds_::PoseStamped_"
    assert len(p.wait_for("sent")) == 1
    states = run.result.states["p_W"]
    assert np.linalg.norm(states[0] - np.asarray(cfg.start_p_W)) < 0.05
    assert np.linalg.norm(states[-1] - np.asarray(goal)) < 0.2, f"ended at {states[-1]}, goal {goal}"
