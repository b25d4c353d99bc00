"""``cufund bag RUN --out DIR``: a run's log as a ROS 2 bag (rosbag2, ``sqlite3`` or ``mcap`` storage, written by
``rosbags``), which ``ros2 bag play``, ``rosbags`` and Foxglove open as a real robot's bag.

Every CDR channel of the run's ``run.mcap`` becomes a bag topic of the same name and type, its messages the log's
CDR bytes unchanged and stamped with their log time (when they became visible in the run): the standard messages
(``sensor_msgs/msg/Imu`` on ``<imu topic>/ros``, ``sensor_msgs/msg/PointCloud2`` on the LiDAR topic in
livox_ros_driver2's point layout, ``nav_msgs/msg/Odometry``, ``geometry_msgs/msg/PoseStamped``, ``/tf``,
``/tf_static``, ``/clock``, ``nav_msgs/msg/Path``) and cufund's exact ``cufund_msgs/msg/*`` (their ``.msg`` text is in
the bag's metadata, so ``rosbags`` decodes them too). The JSON channels (scene, diagnostics) have no ROS 2 type and
are left out (listed in the summary). The run's scenario goes into the bag's ``custom_data`` (``cufund.config``), so
that ``cufund odometry BAG`` uses its extrinsics as it does on the log. The serialisation is the log's: nothing is
encoded again here (:mod:`cufund.logs.ros2`, :mod:`cufund.logs.codecs`).
"""

from __future__ import annotations

import argparse
import os
import shutil
import struct
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cufund.logs.rosbag2_reader import rosbags_typestore

__all__ = ["BagSummary", "STORAGES", "add_arguments", "run", "write_bag"]

STORAGES = ("sqlite3", "mcap")
"""rosbag2 storage plugins ``cufund bag`` writes (``--storage``)."""

EXIT_OK, EXIT_INVALID = 0, 2


@dataclass
class BagSummary:
    """What :func:`write_bag` wrote."""

    path: Path
    storage: str
    topics: dict[str, tuple[str, int]] = field(default_factory=dict)
    """Bag topic -> (ROS 2 type, message count)."""
    skipped: dict[str, str] = field(default_factory=dict)
    """Log channels left out -> why (no ROS 2 type)."""


def _log_messages(log: Path) -> Iterator[tuple[Any, Any, Any]]:
    """(schema, channel, message) of every message of the log in log-time order (the official ``mcap`` reader)."""
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    try:
        stream = open(log, "rb")
    except OSError as exc:
        raise ValueError(f"cannot open log {str(log)!r}: {exc}") from exc
    with stream:
        try:
            yield from make_reader(stream).iter_messages(log_time_order=True)
        except (McapError, EOFError, struct.error, KeyError, RuntimeError) as exc:
            raise ValueError(f"{str(log)!r} is not a complete MCAP log: {exc}") from exc


def _qos(topic: str) -> list[Any]:
    """The offered QoS a driver gives ``topic``: reliable, keep-last; ``/tf_static`` transient-local (latched)."""
    from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime

    latched = topic == "/tf_static"
    zero = QosTime(sec=0, nsec=0)
    return [
        Qos(
            history=QosHistory.KEEP_LAST,
            depth=1 if latched else 100,
            reliability=QosReliability.RELIABLE,
            durability=QosDurability.TRANSIENT_LOCAL if latched else QosDurability.VOLATILE,
            deadline=zero,
            lifespan=zero,
            liveliness=QosLiveliness.AUTOMATIC,
            liveliness_lease_duration=zero,
            avoid_ros_namespace_conventions=False,
        )
    ]


def write_bag(log: str | os.PathLike[str], out: str | os.PathLike[str], storage: str = "sqlite3") -> BagSummary:
    """Writes the ROS 2 bag of the cufund log ``log`` (a ``run.mcap``, or a run folder holding one) to the new
    folder ``out`` with ``storage`` (:data:`STORAGES`). ValueError naming the problem for a missing or damaged log,
    an existing ``out`` or an unknown storage."""
    try:
        from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
    except ImportError as exc:
        raise ValueError(f"cufund bag needs rosbags (pip install 'cufund[ros2]'): {exc}") from exc

    from cufund.logs.mcap_reader import log_metadata

    log, out = Path(log), Path(out)
    if log.is_dir():
        log = log / "run.mcap"
    if storage not in STORAGES:
        raise ValueError(f"storage: expected one of {', '.join(STORAGES)}, got {storage!r}")
    if out.exists():
        raise ValueError(f"--out {str(out)!r} exists already (a bag is written to a new folder)")
    if not log.is_file():
        raise ValueError(f"{str(log)!r}: no such log (give a run folder or its run.mcap)")
    meta = log_metadata(log)  # McapReadError (a ValueError) for a file that is not a cufund log
    typestore = rosbags_typestore()
    summary = BagSummary(out, storage)
    writer = Writer(out, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin[storage.upper()])
    connections: dict[int, Any] = {}
    counts: dict[str, int] = {}
    opened = written = False
    try:
        writer.open()
        opened = True
        for key in ("config", "version", "scenario"):
            if key in meta:
                writer.set_custom_data(f"cufund.{key}", meta[key])
        writer.set_custom_data("cufund.source", log.name)
        for schema, channel, message in _log_messages(log):
            conn = connections.get(channel.id)
            if conn is None:
                if channel.message_encoding != "cdr" or schema is None or schema.encoding != "ros2msg":
                    summary.skipped[channel.topic] = f"{channel.message_encoding} ({schema and schema.name})"
                    connections[channel.id] = False
                    continue
                msgdef = schema.data.decode()
                from rosbags.typesys import get_types_from_msg

                if schema.name not in typestore.fielddefs:
                    typestore.register(get_types_from_msg(msgdef, schema.name))
                conn = writer.add_connection(
                    channel.topic,
                    schema.name,
                    msgdef=msgdef,
                    rihs01=typestore.hash_rihs01(schema.name),
                    offered_qos_profiles=_qos(channel.topic),
                )
                connections[channel.id] = conn
                summary.topics[channel.topic] = (schema.name, 0)
            if conn is False:
                continue
            writer.write(conn, message.log_time, message.data)
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
        written = True
    except WriterError as exc:
        raise ValueError(f"writing the bag {str(out)!r}: {exc}") from exc
    finally:
        if writer.storage is not None:
            writer.close()
        if opened and not written:  # the folder this call made: no partial bag that reads as a complete one
            shutil.rmtree(out, ignore_errors=True)
    summary.topics = {t: (ty, counts.get(t, 0)) for t, (ty, _) in summary.topics.items()}
    return summary


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("run", type=Path, help="a run folder written by cufund run (or its run.mcap)")
    p.add_argument("--out", type=Path, required=True, help="the bag folder to write (must not exist)")
    p.add_argument(
        "--storage", choices=STORAGES, default="sqlite3", help="rosbag2 storage plugin (default sqlite3, ROS 2's)"
    )


def run(args: argparse.Namespace) -> int:
    try:
        summary = write_bag(args.run, args.out, args.storage)
    except ValueError as exc:
        print(f"cufund: {exc}", file=sys.stderr)
        return EXIT_INVALID
    width = max((len(t) for t in summary.topics), default=0)
    print(f"ROS 2 bag ({summary.storage}): {summary.path.resolve()}")
    for topic, (msgtype, count) in summary.topics.items():
        print(f"  {topic:<{width}}  {msgtype}  {count}")
    if summary.skipped:
        print(f"left out (no ROS 2 type): {', '.join(sorted(summary.skipped))}")
    return EXIT_OK
