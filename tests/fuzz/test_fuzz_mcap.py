"""Fuzz: reading MCAP logs (read_mcap, log_topics, log_metadata) on hostile files: crafted channels with valid
framing and hostile metadata and payloads (class names of a gadget module, of the standard library, tags and dtypes
that must not be trusted, random JSON and bytes), and byte-level damage to a real cufund log (cut, flipped,
overwritten length fields, inserted garbage). Each case must end in data or a clean error (McapReadError is a
ValueError): never a crash, a hang, or the gadget module imported (it creates a marker file when imported)."""

from __future__ import annotations

import io
import json
import struct

import numpy as np
import pytest
from fuzz_support import expect_good, fuzz_settings
from hypothesis import given
from hypothesis import strategies as st

GADGET = "cufund_fuzz_gadget"
CALL = f"""
import os, sys
try:
    result = (len(log_metadata(path)), len(log_topics(path)), sum(1 for _ in read_mcap(path)))
finally:
    if "{GADGET}" in sys.modules or os.path.exists(marker):
        raise SystemError("reading the log imported the gadget module the file names")
"""
SETUP = "import sys\nfrom cufund.logs import log_metadata, log_topics, read_mcap\n"

CLASS_NAMES = [
    f"{GADGET}:Gadget",
    f"{GADGET}:GadgetEnum",
    "subprocess:Popen",
    "logging:FileHandler",
    "os:system",
    "builtins:eval",
    "cufund.core.messages:MissionState",
    "cufund.core.messages:FlightMode",
    "cufund.core.messages:Odometry",
    "cufund.core.messages:PointCloud",
    "cufund.core.messages:Imu",
    "cufund.core.messages:Topics",
    "cufund.core.messages:np",
    "cufund.planning.diagnostics:PlannerDiagnostics",
    "cufund.logs.message_classes:_registered",
    "",
    ":",
    "x" * 300,
    "cufund.core.messages:Odometry.__init__",
]
TAGS = [
    "$dataclass",
    "$enum",
    "$ndarray",
    "$scalar",
    "$tuple",
    "$dict",
    "$float",
    "fields",
    "value",
    "dtype",
    "shape",
    "values",
    "base64",
    "t",
    "state",
    "reason",
    "progress",
    "cufund",
    "data",
    "point_stride",
    "dtypes",
    "frame",
    "__class__",
]
STRINGS = CLASS_NAMES + [
    "<f8",
    "<i4",
    "|b1",
    "O",
    "V8",
    "|S3",
    "<U4",
    "[('a', 'O')]",
    "<c16",
    "nan",
    "inf",
    "1e309",
    "AAAA",
    "////",
    "fly",
]
CODECS = ["json", "cdr", "foxglove.PointCloud", "foxglove.RawImage", "foxglove.LocationFix", "pickle", ""]

json_values = st.recursive(
    st.one_of(
        st.none(),
        st.booleans(),
        st.integers(-(2**70), 2**70),
        st.floats(allow_nan=False, allow_infinity=False),
        st.sampled_from(STRINGS),
        st.text(max_size=8),
    ),
    lambda children: st.one_of(
        st.lists(children, max_size=4), st.dictionaries(st.sampled_from(TAGS), children, max_size=4)
    ),
    max_leaves=24,
)


def _gadget_dir(tmp_path_factory) -> tuple[str, str]:
    folder = tmp_path_factory.mktemp("gadget")
    marker = folder / "marker"
    (folder / f"{GADGET}.py").write_text(
        f"import dataclasses, enum, pathlib\npathlib.Path({str(marker)!r}).write_text('imported')\n"
        "@dataclasses.dataclass\nclass Gadget:\n    t: float = 0.0\n"
        "class GadgetEnum(enum.Enum):\n    A = 'a'\n"
    )
    return str(folder), str(marker)


def _crafted(channels: list[tuple[str, dict[str, str], list[bytes]]], chunked: bool) -> bytes:
    from mcap.writer import CompressionType, Writer

    out = io.BytesIO()
    writer = Writer(out, compression=CompressionType.LZ4 if chunked else CompressionType.NONE, use_chunking=chunked)
    writer.start(profile="", library="fuzz")
    schema = writer.register_schema(name="fuzz", encoding="jsonschema", data=b"{}")
    for topic, metadata, payloads in channels:
        channel = writer.register_channel(topic=topic, message_encoding="json", schema_id=schema, metadata=metadata)
        for k, payload in enumerate(payloads):
            writer.add_message(channel, log_time=k, data=payload, publish_time=k)
    writer.finish()
    return out.getvalue()


@st.composite
def channel_metadata(draw) -> dict[str, str]:
    meta = {"cufund.codec": draw(st.sampled_from(CODECS)), "cufund.class": draw(st.sampled_from(CLASS_NAMES))}
    if draw(st.booleans()):
        meta["cufund.layout"] = draw(
            st.one_of(
                st.just(json.dumps([["t", "t", "f8", [], False]])), json_values.map(json.dumps), st.text(max_size=20)
            )
        )
    if draw(st.booleans()):
        del meta[draw(st.sampled_from(sorted(meta)))]
    return meta


payloads = st.one_of(
    json_values.map(lambda v: json.dumps(v).encode()),
    st.binary(max_size=64),
    st.just(b"[" * 100_000 + b"]" * 100_000),
    st.just(b"\0\1\0\0" + bytes(8)),
)


@fuzz_settings
@given(
    channels=st.lists(
        st.tuples(
            st.sampled_from(["/mission/state", "/sensors/imu", "/sensors/lidar", "/x"]),
            channel_metadata(),
            st.lists(payloads, min_size=1, max_size=3),
        ),
        min_size=1,
        max_size=3,
    ),
    chunked=st.booleans(),
)
def test_crafted_channels(server, tmp_path_factory, channels, chunked):
    folder, marker = _gadget_dir(tmp_path_factory)
    path = tmp_path_factory.mktemp("mcap") / "run.mcap"
    path.write_bytes(_crafted(channels, chunked))
    outcome, detail = server.run(
        "mcap", SETUP + f"sys.path.insert(0, {folder!r})\n", CALL, {"path": str(path), "marker": marker}
    )
    expect_good(outcome, detail)


_BASE: dict[str, bytes] = {}


def _base_log(tmp_path_factory) -> bytes:
    """A real log of every codec (CDR odometry with its views, IMU, point clouds, JSON, JSON with an enum)."""
    if "log" not in _BASE:
        from cufund.core import messages as M
        from cufund.logs import McapLogger

        path = tmp_path_factory.mktemp("base") / "base.mcap"
        with McapLogger(path, {"scenario": "fuzz", "config": "name: fuzz\n"}, block_messages=4) as log:
            for k in range(12):
                t = 0.01 * k
                log.write(
                    "/truth/odometry",
                    M.Odometry(t, np.ones(3), np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3)),
                    k,
                    k,
                )
                log.write("/sensors/imu", M.Imu(t, np.zeros(3), np.zeros(3)), k, k)
                log.write("/mission/state", M.MissionState(t, "fly", "", k), k, k)
                if k % 4 == 0:
                    n = 5
                    log.write(
                        "/sensors/lidar",
                        M.PointCloud(
                            t,
                            np.zeros(n),
                            np.zeros((n, 3), np.float32),
                            np.ones(n, np.float32),
                            np.zeros(n, np.float32),
                            np.zeros(n, np.uint8),
                            0,
                        ),
                        k,
                        k,
                    )
                    log.write("/commander/flight_mode", M.FlightModeCommand(t, M.FlightMode.POSITION), k, k)
        _BASE["log"] = path.read_bytes()
    return _BASE["log"]


damage = st.lists(
    st.tuples(st.sampled_from(["cut", "flip", "u64", "u32", "insert"]), st.floats(0, 1), st.integers(0, 2**64 - 1)),
    min_size=1,
    max_size=4,
)


def _damage(data: bytes, ops: list[tuple[str, float, int]]) -> bytes:
    buf = bytearray(data)
    for op, where, value in ops:
        at = min(int(where * len(buf)), max(len(buf) - 1, 0))
        if op == "cut":
            del buf[at:]
        elif op == "flip" and buf:
            buf[at] ^= (value % 255) + 1
        elif op == "u64":
            buf[at : at + 8] = struct.pack("<Q", value)
        elif op == "u32":
            buf[at : at + 4] = struct.pack("<I", value % 2**32)
        elif op == "insert":
            buf[at:at] = value.to_bytes(8, "little")
    return bytes(buf)


@fuzz_settings
@given(ops=damage)
def test_damaged_logs(server, tmp_path_factory, ops):
    folder, marker = _gadget_dir(tmp_path_factory)
    path = tmp_path_factory.mktemp("mcap") / "run.mcap"
    path.write_bytes(_damage(_base_log(tmp_path_factory), ops))
    outcome, detail = server.run(
        "mcap", SETUP + f"sys.path.insert(0, {folder!r})\n", CALL, {"path": str(path), "marker": marker}
    )
    expect_good(outcome, detail)


def test_the_base_log_reads_back(tmp_path_factory):
    """The campaign damages a log that reads whole (else every case would be a trivially clean error)."""
    from cufund.logs import read_mcap

    path = tmp_path_factory.mktemp("check") / "base.mcap"
    path.write_bytes(_base_log(tmp_path_factory))
    topics = [r.topic for r in read_mcap(path)]
    assert len(topics) == 12 * 3 + 3 * 2 and {"/sensors/lidar", "/commander/flight_mode"} <= set(topics)


def test_a_gadget_is_noticed(tmp_path_factory):
    """The check can fail: a call that imports the gadget raises (run in its own interpreter, not the server, so
    the campaign's table holds only real cases)."""
    import subprocess
    import sys

    folder, marker = _gadget_dir(tmp_path_factory)
    code = (
        SETUP
        + f"sys.path.insert(0, {folder!r})\npath, marker = '/nonexistent', {marker!r}\n"
        + CALL.replace("    result = (", f"    import {GADGET}\n    result = (")
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode != 0 and "imported the gadget module" in done.stderr, done.stderr


pytestmark = pytest.mark.filterwarnings("ignore::ResourceWarning")
