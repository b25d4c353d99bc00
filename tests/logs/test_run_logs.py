"""Every built-in scenario's ``run.mcap`` is a log the ROS 2 tools read: the ``mcap`` reader and
``mcap-ros2-support`` decode every channel, every frame a message names resolves through ``/tf`` and
``/tf_static`` to ``world``, clouds decode to the simulator's points, and cufund's readers still read it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from cufund.logs import read_mcap
from cufund.scenarios import run_folder
from cufund.scenarios.schema import available_scenarios, load_scenario

SCENARIOS = sorted(available_scenarios())


def _frames_named(msg, schema_name: str) -> set[str]:
    """Every frame id a decoded message names (headers, child frames, scene entities)."""
    out: set[str] = set()
    header = getattr(msg, "header", None)
    if header is not None:
        out.add(header.frame_id)
    child = getattr(msg, "child_frame_id", None)
    if child:
        out.add(child)
    for pose in getattr(msg, "poses", ()):  # nav_msgs/Path
        out.add(pose.header.frame_id)
    return out


def _walk_to_world(frame: str, parents: dict[str, str]) -> bool:
    seen = set()
    while frame != "world":
        if frame in seen or frame not in parents:
            return False
        seen.add(frame)
        frame = parents[frame]
    return True


@pytest.fixture(scope="module", params=SCENARIOS)
def run_log(request, tmp_path_factory):
    """(name, run.mcap, the LiDAR frames the simulator published) of a 1.5 s run of each built-in scenario."""
    out = tmp_path_factory.mktemp(request.param)
    config = load_scenario(request.param, ["duration=1.5"])
    published = []
    write = run_folder._Excluding.write

    def recording(self, topic, message, log_time_ns, publish_time_ns):
        if type(message).__name__ == "PointCloud":
            published.append(message)
        write(self, topic, message, log_time_ns, publish_time_ns)

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(run_folder._Excluding, "write", recording)
        run_folder.run_into_folder(config, out, plots=False, replay=False)
    return request.param, out / "run.mcap", published


def test_every_channel_decodes_and_every_frame_resolves_to_world(run_log):
    name, path, _ = run_log
    factory = DecoderFactory()
    parents: dict[str, str] = {}
    named: set[str] = set()
    counts: dict[str, int] = {}
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.message_encoding == "json":
                obj = json.loads(message.data)
                for entity in obj.get("entities", []) if schema.name == "foxglove.SceneUpdate" else []:
                    named.add(entity["frame_id"])
                continue
            assert channel.message_encoding == "cdr" and schema.encoding == "ros2msg", channel.topic
            msg = factory.decoder_for("cdr", schema)(message.data)
            if schema.name == "tf2_msgs/msg/TFMessage":
                for tf in msg.transforms:
                    child, parent = tf.child_frame_id, tf.header.frame_id
                    assert parents.setdefault(child, parent) == parent, f"{child} has two parents"
                    named.add(parent)
            else:
                named |= _frames_named(msg, schema.name)
    assert "/tf_static" in counts and "/clock" in counts, (name, sorted(counts))
    assert "/truth/point_cloud" not in counts  # off by default (log.truth_cloud)
    if name.startswith("square"):  # the waypoints planner: its reference is known before the run
        assert counts["/planner/path"] == 1
    unresolved = sorted(f for f in named if not _walk_to_world(f, parents))
    assert not unresolved, f"{name}: frames {unresolved} do not resolve to world through /tf ({parents})"


def test_clouds_decode_to_the_simulators_points(run_log):
    name, path, published = run_log
    if not published:
        pytest.skip(f"{name} has no LiDAR")
    factory = DecoderFactory()
    with open(path, "rb") as f:
        raw = [
            factory.decoder_for("cdr", s)(m.data)
            for s, c, m in make_reader(f).iter_messages(log_time_order=True)
            if s.name == "sensor_msgs/msg/PointCloud2"
        ]
    logged = [r.message for r in read_mcap(path) if type(r.message).__name__ == "PointCloud"]
    assert len(raw) == len(logged) == len(published)
    for msg, back, cloud in zip(raw, logged, published, strict=True):
        points = np.frombuffer(bytes(msg.data), np.uint8).reshape(-1, msg.point_step)
        xyz = points[:, :12].copy().view("<f4")  # x, y, z at offsets 0, 4, 8 (decoded without cufund's code)
        assert np.array_equal(xyz, cloud.points_L) and np.array_equal(back.points_L, cloud.points_L)
        assert np.array_equal(points[:, 17], cloud.channel)  # line
        assert np.allclose(back.dt, cloud.dt, rtol=0, atol=1e-9) and back.t == pytest.approx(cloud.t, abs=1e-9)


def test_the_shipped_foxglove_layout_names_only_what_a_tunnel_log_has(run_log):
    """cufund.foxglove.json (in the package): its 3-D topics, plot paths and script inputs are in the tunnel's log,
    with the fields the plots read."""
    name, path, _ = run_log
    if name != "tunnel":
        pytest.skip("checked on the tunnel's log")
    from importlib.resources import files

    layout = json.loads((files("cufund.logs") / "cufund.foxglove.json").read_text())
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    schemas = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
    panels = layout["configById"]
    assert set(panels["3D!cufund"]["topics"]) <= set(schemas)
    script = next(iter(layout["userNodes"].values()))
    scripted = script["sourceCode"].split("export const output = ")[1].split('"')[1]
    for panel in (panels["Plot!position"], panels["Plot!error"]):
        for entry in panel["paths"]:
            topic, field = entry["value"].split(".", 1)
            if topic == scripted:
                continue
            assert topic in schemas, topic
            assert field.split("[")[0] in schemas[topic].data.decode().split(), (topic, field)
    for topic in ("/truth/odometry", "/estimator/odometry"):
        assert f'"{topic}"' in script["sourceCode"] and topic in schemas
    assert panels["RawMessages!mission"]["topicPath"] in schemas
    for panel_id in _panels(layout["layout"]):
        assert panel_id in panels


def _panels(node) -> list[str]:
    if isinstance(node, str):
        return [node]
    return _panels(node["first"]) + _panels(node["second"])
