"""A log file must never run code: crafted MCAP logs that name a "gadget" class (a module whose import, or a class
whose construction, creates a marker file) in a message body, in the channel metadata, in an enum tag or in a
nested field. Reading them (read_mcap, LogPlayer, ``cufund replay``, ``cufund odometry``) fails with an error
naming the channel; the marker is never created and the gadget module never imported."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.writer import CompressionType, Writer

from cufund.logs import LogPlayer, McapReadError, read_mcap

GADGET = "cufund_gadget_probe"


@pytest.fixture()
def gadget(tmp_path, monkeypatch):
    """An importable module that creates ``marker`` when imported and when its classes are built."""
    marker = tmp_path / "marker"
    (tmp_path / f"{GADGET}.py").write_text(
        "import dataclasses, enum, pathlib\n"
        f"MARKER = pathlib.Path({str(marker)!r})\n"
        "MARKER.write_text('imported')\n"
        "@dataclasses.dataclass\n"
        "class Gadget:\n"
        "    t: float = 0.0\n"
        "    def __post_init__(self):\n"
        "        MARKER.write_text('called')\n"
        "class GadgetEnum(enum.Enum):\n"
        "    A = 'a'\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    sys.modules.pop(GADGET, None)
    yield marker
    sys.modules.pop(GADGET, None)


def _mission_state(**fields):
    return {"t": 0.0, "state": "fly", "reason": "", "progress": 0, **fields}


def _write_log(path: Path, channels: list[tuple[str, dict[str, str], list[bytes]]]) -> None:
    """An MCAP log (summary and all) with one channel per (topic, metadata, payloads)."""
    with open(path, "wb") as f:
        writer = Writer(f, compression=CompressionType.LZ4)
        writer.start(profile="", library="test")
        schema = writer.register_schema(name="cufund.Probe", encoding="jsonschema", data=b"{}")
        for topic, metadata, payloads in channels:
            channel = writer.register_channel(topic=topic, message_encoding="json", schema_id=schema, metadata=metadata)
            for k, payload in enumerate(payloads):
                writer.add_message(channel, log_time=k, data=payload, publish_time=k)
        writer.finish()


JSON_STATE = {"cufund.codec": "json", "cufund.class": "cufund.core.messages:MissionState"}

CASES: dict[str, list[tuple[str, dict[str, str], list[bytes]]]] = {
    "point cloud body": [
        (
            "/mission/state",
            {"cufund.codec": "foxglove.PointCloud", "cufund.class": "cufund.core.messages:PointCloud"},
            [
                json.dumps(
                    {
                        "fields": [],
                        "point_stride": 4,
                        "data": "",
                        "cufund": {"dtypes": {}, "fields": {"frame": {"$dataclass": f"{GADGET}:Gadget", "fields": {}}}},
                    }
                ).encode()
            ],
        )
    ],
    "body field": [
        (
            "/mission/state",
            JSON_STATE,
            [json.dumps(_mission_state(state={"$dataclass": f"{GADGET}:Gadget", "fields": {}})).encode()],
        )
    ],
    "channel metadata": [
        (
            "/mission/state",
            {"cufund.codec": "json", "cufund.class": f"{GADGET}:Gadget"},
            [json.dumps({"t": 0.0}).encode()],
        )
    ],
    "enum tag": [
        (
            "/mission/state",
            JSON_STATE,
            [json.dumps(_mission_state(state={"$enum": f"{GADGET}:GadgetEnum", "value": "a"})).encode()],
        )
    ],
    "nested field": [
        (
            "/mission/state",
            JSON_STATE,
            [
                json.dumps(
                    _mission_state(
                        reason={"$tuple": [1, {"$dict": {"x": [{"$dataclass": f"{GADGET}:Gadget", "fields": {}}]}}]}
                    )
                ).encode()
            ],
        )
    ],
    "stdlib class": [
        (
            "/mission/state",
            JSON_STATE,
            [
                json.dumps(
                    _mission_state(state={"$dataclass": "logging:FileHandler", "fields": {"filename": "MARKER"}})
                ).encode()
            ],
        )
    ],
    "cdr metadata": [
        (
            "/sensors/imu",
            {
                "cufund.codec": "cdr",
                "cufund.class": f"{GADGET}:Gadget",
                "cufund.layout": json.dumps([["t", "t", "f8", [], False]]),
            },
            [b"\0\1\0\0" + bytes(8)],
        )
    ],
}


@pytest.mark.parametrize("case", list(CASES))
def test_reading_a_crafted_log_never_runs_the_class_it_names(tmp_path, gadget, case):
    path = _write_case(tmp_path, case, gadget)
    with pytest.raises(McapReadError) as error:
        list(read_mcap(path))
    topic = CASES[case][0][0]
    assert f"channel {topic!r}" in str(error.value)
    assert "not an allowed message class" in str(error.value)
    assert not gadget.exists(), gadget.read_text()
    assert GADGET not in sys.modules


@pytest.mark.parametrize("case", ["channel metadata", "point cloud body"])
def test_log_player_refuses_a_crafted_log(tmp_path, gadget, case):
    path = _write_case(tmp_path, case, gadget)
    with pytest.raises(McapReadError, match="not an allowed message class"):
        player = LogPlayer(path, topics=["/mission/state"])
        player.reset()
        list(player._records)
    assert not gadget.exists()


@pytest.mark.parametrize("command", ["replay", "odometry"])
@pytest.mark.parametrize("case", ["channel metadata", "body field", "enum tag"])
def test_the_cli_refuses_a_crafted_log(tmp_path, gadget, command, case):
    """What the probe ran: ``cufund replay`` / ``cufund odometry`` on a crafted run.mcap."""
    path = _write_log_on(tmp_path, case, gadget, ("/sensors/imu", "/sensors/lidar", "/truth/odometry"))
    args = [sys.executable, "-m", "cufund.apps.cli", command, str(path)]
    args += ["--no-wait"] if command == "replay" else ["--out", str(tmp_path / "odo")]
    env = {
        **os.environ,
        "PYTHONPATH": f"{tmp_path}{os.pathsep}{os.environ.get('PYTHONPATH', '')}",
        "PYTHONWARNINGS": "ignore",
    }
    done = subprocess.run(args, capture_output=True, text=True, env=env, timeout=120)
    assert done.returncode == 2, done.stderr
    assert "not an allowed message class" in done.stderr and "channel" in done.stderr
    assert "Traceback" not in done.stderr
    assert not gadget.exists()


def test_a_registered_user_class_is_read_back(tmp_path):
    """The public way to read user messages in a fresh process: register the class."""
    import dataclasses

    from cufund.logs import McapLogger, message_classes, register_message_class

    @dataclasses.dataclass(frozen=True)
    class UserMessage:
        t: float
        label: str

    path = tmp_path / "user.mcap"
    with McapLogger(path) as log:
        log.write("/user", UserMessage(0.5, "x"), 1, 1)
    message_classes._registered.pop(message_classes.class_path(UserMessage))  # as if another process read it
    with pytest.raises(McapReadError, match="channel '/user'.*not an allowed"):
        list(read_mcap(path))
    register_message_class(UserMessage)
    assert [r.message for r in read_mcap(path)] == [UserMessage(0.5, "x")]
    with pytest.raises(TypeError, match="dataclass or an enum"):
        register_message_class(len)


def _write_case(tmp_path: Path, case: str, marker: Path) -> Path:
    path = tmp_path / "run.mcap"
    channels = [(t, m, [p.replace(b"MARKER", str(marker).encode()) for p in ps]) for t, m, ps in CASES[case]]
    _write_log(path, channels)
    return path


def _write_log_on(tmp_path: Path, case: str, marker: Path, topics: tuple[str, ...]) -> Path:
    """The case's channel on each of ``topics`` (what ``cufund odometry`` and ``replay`` read)."""
    path = tmp_path / "run.mcap"
    _, metadata, payloads = CASES[case][0]
    _write_log(
        path, [(topic, metadata, [p.replace(b"MARKER", str(marker).encode()) for p in payloads]) for topic in topics]
    )
    return path


def test_a_log_with_the_0_1_class_names_reads(tmp_path):
    """cufund 0.1 recorded its messages as ``cufund.messages:...`` (and the planner's diagnostics under
    cufund.planning): those names map to the classes' homes now, by string, and the log reads."""
    path = tmp_path / "old.mcap"
    old = {"cufund.codec": "json", "cufund.class": "cufund.messages:MissionState"}
    state = dict(_mission_state(), state="fly")
    _write_log(path, [("/mission/state", old, [json.dumps(state).encode()])])
    (msg,) = [r.message for r in read_mcap(path)]
    from cufund.core.messages import MissionState

    assert isinstance(msg, MissionState) and msg.state == "fly"
    from cufund.core.moved import new_class_path

    assert new_class_path("cufund.messages:Imu") == "cufund.core.messages:Imu"
    assert new_class_path("cufund.planning.diagnostics:PlannerDiagnostics") == "cufund.core.messages:PlannerDiagnostics"
    assert new_class_path("os:system") == "os:system"  # not moved: still refused by the allowlist
