"""The bridge's DDS participant: Cyclone DDS configured for this host only, ROS 2's topic and QoS conventions.

Safe by default: :func:`cyclone_config` binds Cyclone DDS to the loopback interface, turns multicast off and
discovers peers by unicast on 127.0.0.1 only (what ROS 2's ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` does).
Cyclone binds its unicast receive sockets to the wildcard address whatever its configuration (no option changes
that, as of Cyclone 11; eclipse-cyclonedds/cyclonedds#1923), and would take what another host sends to this host's
ports; on Linux the domain's wildcard sockets are therefore bound to the loopback device (``SO_BINDTODEVICE lo``:
the kernel then drops what arrives on any other interface; :func:`confine_to_loopback`). ``expose=True`` (the
``--expose`` flag, ``ros2.expose``) leaves Cyclone's defaults (every interface, multicast discovery). The
configuration is passed to the domain explicitly, never read from the environment, so a stray ``CYCLONEDDS_URI``
cannot widen it.

ROS 2 on DDS: topic ``/a/b`` is the DDS topic ``rt/a/b``; type ``pkg/msg/T`` is ``pkg::msg::dds_::T_``
(:func:`cufund.apps.ros2.idl.dds_type_name`); samples are plain (XCDR1) little-endian CDR, as rmw_cyclonedds and
rmw_fastrtps write them.
"""

from __future__ import annotations

import os
import socket
import threading
import warnings
from dataclasses import dataclass
from typing import Any

from cyclonedds.core import DDSException
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from . import idl

__all__ = ["QOS", "DdsParticipant", "QosProfile", "confine_to_loopback", "cyclone_config", "dds_topic_name"]

MAX_PARTICIPANTS = 32
"""Participants per host and domain the loopback configuration discovers (participant indices 0..31)."""


def dds_topic_name(ros_name: str) -> str:
    """``/imu`` -> ``rt/imu`` (a ROS 2 topic's DDS name); ValueError for a name that is not absolute."""
    if not isinstance(ros_name, str) or not ros_name.startswith("/") or ros_name.endswith("/") or "//" in ros_name:
        raise ValueError(f"a ROS 2 topic name must be absolute like /imu or /livox/lidar, got {ros_name!r}")
    return "rt" + ros_name


def cyclone_config(domain_id: int, expose: bool = False) -> str:
    """The Cyclone DDS XML of the bridge's domain. Loopback only (``expose`` False): interface ``lo``, no
    multicast, unicast discovery of the participants on 127.0.0.1."""
    if expose:
        return f'<CycloneDDS><Domain Id="{int(domain_id)}"/></CycloneDDS>'
    return (
        f'<CycloneDDS><Domain Id="{int(domain_id)}">'
        '<General><Interfaces><NetworkInterface name="lo"/></Interfaces>'
        "<AllowMulticast>false</AllowMulticast></General>"
        "<Discovery><ParticipantIndex>auto</ParticipantIndex>"
        f"<MaxAutoParticipantIndex>{MAX_PARTICIPANTS - 1}</MaxAutoParticipantIndex>"
        '<Peers><Peer Address="127.0.0.1"/></Peers></Discovery>'
        "</Domain></CycloneDDS>"
    )


@dataclass(frozen=True)
class QosProfile:
    """A ROS 2 QoS profile: reliability, durability, history depth."""

    reliable: bool = True
    transient_local: bool = False
    depth: int = 10

    def qos(self) -> Qos:
        return Qos(
            Policy.Reliability.Reliable(max_blocking_time=1_000_000_000)
            if self.reliable
            else Policy.Reliability.BestEffort,
            Policy.Durability.TransientLocal if self.transient_local else Policy.Durability.Volatile,
            Policy.History.KeepLast(self.depth),
            Policy.DataRepresentation(use_cdrv0_representation=True),
        )


QOS = {
    "sensor_data": QosProfile(reliable=False, depth=5),
    "default": QosProfile(),
    "tf": QosProfile(depth=100),
    "tf_static": QosProfile(transient_local=True, depth=1),
    "clock": QosProfile(depth=1),
    "ack": QosProfile(depth=1000),
}
"""ROS 2's profiles (rclcpp's ``SensorDataQoS``, the default, tf2's ``DynamicBroadcasterQoS`` and
``StaticBroadcasterQoS``), the clock (reliable, so best-effort ``ClockQoS`` readers match it too), and the
lockstep answers (reliable, deep: none is lost)."""


def _socket_fds() -> set[int]:
    """This process's socket file descriptors (Linux: /proc/self/fd; elsewhere none)."""
    out: set[int] = set()
    try:
        names = os.listdir("/proc/self/fd")
    except OSError:
        return out
    for fd in names:
        try:
            if os.readlink(f"/proc/self/fd/{fd}").startswith("socket:"):
                out.add(int(fd))
        except OSError:
            continue
    return out


def confine_to_loopback(domain_id: int, fds: set[int]) -> list[int]:
    """Bind the UDP sockets among ``fds`` that listen on the wildcard address at one of the domain's ports
    (7400 + 250 d ..) to the loopback device, so that the kernel gives them only what arrives over ``lo`` (this
    host's own traffic). Linux only (``fds`` from /proc/self/fd); returns the ports confined. A socket the kernel
    will not confine is a warning, as the docs say."""
    base = 7400 + 250 * domain_id
    confined = []
    for fd in sorted(fds):
        try:
            s = socket.socket(fileno=fd)
        except OSError:
            continue
        try:
            if s.type != socket.SOCK_DGRAM or s.family not in (socket.AF_INET, socket.AF_INET6):
                continue
            addr, port = s.getsockname()[:2]
            if addr not in ("0.0.0.0", "::") or not base <= port < base + 250:
                continue
            try:
                s.setsockopt(socket.SOL_SOCKET, socket.SO_BINDTODEVICE, b"lo")
            except (AttributeError, OSError) as e:
                warnings.warn(
                    f"ros2: DDS port {port} listens on every interface and could not be bound to the loopback "
                    f"device ({e}); other hosts can send to it",
                    RuntimeWarning,
                    stacklevel=3,
                )
                continue
            confined.append(port)
        except OSError:
            continue
        finally:
            s.detach()
    return confined


_DOMAINS: dict[int, list[Any]] = {}
"""The domains this process configured: id -> [configuration, Domain, participants]. Cyclone configures a domain
once per process; every participant in it shares that configuration; the last one to close releases it."""
_DOMAINS_LOCK = threading.Lock()


def _open_domain(domain_id: int, config: str, loopback: bool) -> Any:
    with _DOMAINS_LOCK:
        found = _DOMAINS.get(domain_id)
        if found is not None:
            if found[0] != config:
                raise ValueError(
                    f"ros2: DDS domain {domain_id} is open in this process with another configuration (expose "
                    "differs); one process uses one setting per domain"
                )
            found[2] += 1
            return found[1]
        before = _socket_fds()
        domain = Domain(domain_id, config)
        if loopback:  # the wildcard sockets Cyclone just opened for the domain
            confine_to_loopback(domain_id, _socket_fds() - before)
        _DOMAINS[domain_id] = [config, domain, 1]
        return domain


def _close_domain(domain_id: int) -> None:
    with _DOMAINS_LOCK:
        found = _DOMAINS.get(domain_id)
        if found is not None:
            found[2] -= 1
            if found[2] <= 0:
                del _DOMAINS[domain_id]


class DdsParticipant:
    """One DDS domain participant speaking ROS 2's conventions; writers take CDR bytes, readers give raw samples
    or decoded :mod:`~cufund.apps.ros2.idl` structs."""

    def __init__(self, domain_id: int = 0, expose: bool = False) -> None:
        if isinstance(domain_id, bool) or not isinstance(domain_id, int) or not 0 <= domain_id <= 232:
            raise ValueError(f"ros2.domain_id must be an integer in [0, 232] (ROS_DOMAIN_ID), got {domain_id!r}")
        self.domain_id = domain_id
        self.expose = expose
        self.config = cyclone_config(domain_id, expose)
        try:
            self._domain = _open_domain(domain_id, self.config, loopback=not expose)
        except DDSException as e:
            raise RuntimeError(f"ros2: could not open DDS domain {domain_id}: {e}") from None
        try:
            self.participant = DomainParticipant(domain_id)
        except DDSException as e:
            _close_domain(domain_id)
            raise RuntimeError(f"ros2: could not open DDS domain {domain_id}: {e}") from None
        self._topics: dict[str, Any] = {}
        self._lock = threading.Lock()
        self.closed = False

    def topic(self, ros_name: str, ros_type: str) -> Any:
        name = dds_topic_name(ros_name)
        with self._lock:
            found = self._topics.get(name)
            if found is not None:
                if found.data_type is not idl.TYPES[ros_type]:
                    raise ValueError(f"ros2: topic {ros_name} is used with two types")
                return found
            if ros_type not in idl.TYPES:
                raise ValueError(f"ros2: unknown ROS 2 type {ros_type!r}; known: {', '.join(sorted(idl.TYPES))}")
            t: Any = Topic(self.participant, name, idl.TYPES[ros_type])
            self._topics[name] = t
            return t

    def writer(self, ros_name: str, ros_type: str, qos: QosProfile) -> RawWriter:
        return RawWriter(DataWriter(self.participant, self.topic(ros_name, ros_type), qos=qos.qos()), ros_name)

    def reader(self, ros_name: str, ros_type: str, qos: QosProfile) -> DataReader:
        return DataReader(self.participant, self.topic(ros_name, ros_type), qos=qos.qos())

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self._topics.clear()
            del self.participant
            del self._domain
            _close_domain(self.domain_id)


class RawWriter:
    """A DDS writer of CDR bytes as :mod:`cufund.logs` encodes them (encapsulation header included)."""

    def __init__(self, writer: DataWriter, ros_name: str) -> None:
        from cyclonedds._clayer import ddspy_write

        self.writer = writer
        self.ros_name = ros_name
        self._write = ddspy_write
        self.count = 0
        self.bytes = 0

    def write(self, data: bytes) -> None:
        pad = (-len(data)) % 4
        if pad:  # a DDS payload is a whole number of 4-byte words; the encapsulation options count the padding
            data = data[:3] + bytes([data[3] | pad]) + data[4:] + b"\0" * pad
        ret = self._write(self.writer._ref, data)
        if ret < 0:
            raise RuntimeError(f"ros2: writing {self.ros_name} failed (DDS return code {ret})")
        self.count += 1
        self.bytes += len(data)

    def matched(self) -> int:
        return len(self.writer.get_matched_subscriptions())
