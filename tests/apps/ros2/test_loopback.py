"""The bridge's DDS stays on this host by default: Cyclone DDS is given the loopback interface, no multicast and
unicast peers on 127.0.0.1, and the sockets it opens show it (read from /proc/net/udp): the sending socket is bound
to 127.0.0.1, none listens on the domain's multicast discovery port, and none is bound to another interface's
address. Cyclone binds its unicast receive sockets to the wildcard address whatever the interface (no option
changes it: eclipse-cyclonedds/cyclonedds#1923, #2090), so the bridge binds those to the loopback device: every
socket of the participant is bound to 127.0.0.1 or to the device lo, where the kernel gives it only this host's
own traffic."""

from __future__ import annotations

import os
import socket
import xml.etree.ElementTree as ET

import pytest

pytest.importorskip("cyclonedds")

from cufund.apps.ros2.dds import QOS, DdsParticipant, cyclone_config

DOMAIN = 150 + os.getpid() % 40


def _socket_inodes() -> set[str]:
    out = set()
    for fd in os.listdir("/proc/self/fd"):
        try:
            link = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            continue
        if link.startswith("socket:["):
            out.add(link[8:-1])
    return out


def _devices() -> dict[tuple[str, int], bytes]:
    """(address, port) -> the device (SO_BINDTODEVICE) of this process's IPv4/IPv6 UDP sockets."""
    out = {}
    for fd in os.listdir("/proc/self/fd"):
        try:
            if not os.readlink(f"/proc/self/fd/{fd}").startswith("socket:["):
                continue
            s = socket.socket(fileno=int(fd))
        except OSError:
            continue
        try:
            if s.type == socket.SOCK_DGRAM and s.family in (socket.AF_INET, socket.AF_INET6):
                addr, port = s.getsockname()[:2]
                out[(addr, port)] = s.getsockopt(socket.SOL_SOCKET, socket.SO_BINDTODEVICE, 16).rstrip(b"\0")
        finally:
            s.detach()
    return out


def _udp_sockets() -> list[tuple[str, int]]:
    """(local address, port) of this process's UDP sockets (IPv4 and IPv6)."""
    mine = _socket_inodes()
    out = []
    for path in ("/proc/net/udp", "/proc/net/udp6"):
        with open(path) as f:
            for line in f.read().splitlines()[1:]:
                parts = line.split()
                if parts[9] in mine:
                    addr, port = parts[1].split(":")
                    out.append((addr, int(port, 16)))
    return out


def test_the_configuration_is_loopback_only_without_multicast():
    root = ET.fromstring(cyclone_config(DOMAIN))
    domain = root.find("Domain")
    assert domain is not None and domain.get("Id") == str(DOMAIN)
    assert [n.get("name") for n in domain.iter("NetworkInterface")] == ["lo"]
    assert domain.findtext("General/AllowMulticast") == "false"
    assert [p.get("Address") for p in domain.iter("Peer")] == ["127.0.0.1"]
    exposed = ET.fromstring(cyclone_config(DOMAIN, expose=True)).find("Domain")
    assert exposed is not None and not list(exposed.iter("NetworkInterface"))  # the flag does change it


def test_the_sockets_are_on_loopback_and_no_multicast_port_is_bound():
    before = set(_udp_sockets())
    dds = DdsParticipant(DOMAIN)
    try:
        dds.writer("/imu", "sensor_msgs/msg/Imu", QOS["sensor_data"])
        dds.reader("/goal_pose", "geometry_msgs/msg/PoseStamped", QOS["default"])
        opened = [s for s in _udp_sockets() if s not in before]
        devices = _devices()
    finally:
        dds.close()
    assert opened, "the participant opened no UDP socket"
    loopback = "0100007F"  # 127.0.0.1 as /proc/net/udp writes it
    wildcard = ("00000000", "00000000000000000000000000000000")
    spdp_multicast_port = 7400 + 250 * DOMAIN
    assert any(addr == loopback for addr, _ in opened), f"no socket bound to 127.0.0.1: {opened}"
    for addr, port in opened:
        assert addr == loopback or addr in wildcard, f"a socket bound to another interface: {addr}:{port}"
        assert port != spdp_multicast_port, "a socket listens for multicast discovery"
    # unicast ports of this domain only: 7400 + 250 d + 10 + 2 i (discovery) and + 11 + 2 i (data), or the sender's
    for addr, port in opened:
        if addr in wildcard:
            assert 7410 + 250 * DOMAIN <= port < 7412 + 250 * DOMAIN + 64, f"unexpected listening port {port}"
    # and every socket is on loopback: 127.0.0.1, or the wildcard address bound to the device lo
    for addr, port in opened:
        if addr != loopback:
            device = devices[("0.0.0.0" if addr == wildcard[0] else "::", port)]
            assert device == b"lo", f"port {port} listens on every interface (device {device!r})"
