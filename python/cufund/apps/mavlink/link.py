"""A MAVLink 2 link over UDP: ``udpout:HOST:PORT`` (send to a listening client) or ``udpin:HOST:PORT`` (listen).

A ``udpin`` link answers the first address that writes to it and keeps that peer until it has been silent for
``peer_timeout_s``, as MAVProxy's and mavlink-router's UDP servers do: datagrams from anyone else meanwhile are
dropped (counted in :attr:`LinkStats.foreign`), so a stray packet cannot take the ground station's stream.

One non-blocking socket and one pymavlink codec per link. Parsing never raises: malformed bytes, bad CRCs and
unknown message ids are counted in :attr:`UdpLink.stats` and dropped. Sockets bind 127.0.0.1 unless the URL names
another address (a ``udpout`` to another host binds the one interface its route leaves by).
"""

from __future__ import annotations

import ipaddress
import socket
import time
from dataclasses import dataclass, field

from pymavlink.dialects.v20 import common as mavlink

_MAX_DATAGRAM = 65535


@dataclass(frozen=True)
class LinkAddress:
    """A parsed link URL."""

    mode: str
    """'udpout' (we send first, to host:port) or 'udpin' (we bind host:port and answer whoever writes)."""
    host: str
    port: int

    @staticmethod
    def parse(url: str, name: str = "link") -> LinkAddress:
        """``udpout:HOST:PORT``, ``udpin:HOST:PORT`` or ``udpin:PORT`` (binds 127.0.0.1); ``udp:`` is ``udpin:``."""
        if not isinstance(url, str):
            raise TypeError(f"{name} must be a string like 'udpout:127.0.0.1:14550', got {type(url).__name__}")
        parts = url.split(":")
        mode = parts[0].lower()
        if mode == "udp":
            mode = "udpin"
        if mode not in ("udpout", "udpin") or len(parts) not in (2, 3):
            raise ValueError(f"{name} must be 'udpout:HOST:PORT' or 'udpin:[HOST:]PORT', got {url!r}")
        host = parts[1] if len(parts) == 3 else "127.0.0.1"
        try:
            port = int(parts[-1])
        except ValueError:
            raise ValueError(f"{name}: the port must be an integer, got {parts[-1]!r} in {url!r}") from None
        if not 0 <= port <= 65535 or (mode == "udpout" and port == 0):
            raise ValueError(f"{name}: port out of range in {url!r}")
        if mode == "udpout" and not host:
            raise ValueError(f"{name}: udpout needs a host, got {url!r}")
        return LinkAddress(mode, host or "127.0.0.1", port)


def _is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _source_address(peer: tuple[str, int]) -> str:
    """The local address this host sends to ``peer`` from (its route's interface; 127.0.0.1 for loopback), so a
    ``udpout`` socket listens on that one interface, never on every one."""
    if _is_loopback(peer[0]):
        return "127.0.0.1"
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        probe.connect(peer)  # UDP: no packet is sent, the kernel only picks the route
        return probe.getsockname()[0]
    except OSError:  # no route (yet): the wildcard is the only way to be reachable when one appears
        return ""
    finally:
        probe.close()


@dataclass
class LinkStats:
    """Counters of one link (read by tests and the endpoint's summary)."""

    received: int = 0
    sent: int = 0
    bad_data: int = 0
    """Datagrams or frames dropped: bad CRC, unknown id, truncated, garbage."""
    send_errors: int = 0
    foreign: int = 0
    """udpin: datagrams dropped because they came from another address than the current peer."""
    by_type: dict[str, int] = field(default_factory=dict)


class UdpLink:
    """One MAVLink 2 UDP link. ``recv()`` returns the messages that arrived; ``send(msg)`` packs with our ids."""

    def __init__(
        self, url: str, system_id: int = 1, component_id: int = 1, name: str = "link", peer_timeout_s: float = 5.0
    ) -> None:
        if (
            isinstance(peer_timeout_s, bool)
            or not isinstance(peer_timeout_s, (int, float))
            or not (peer_timeout_s > 0 and peer_timeout_s < float("inf"))
        ):
            raise ValueError(f"{name}: peer_timeout_s must be a finite time > 0 [s], got {peer_timeout_s!r}")
        self.name = name
        self.peer_timeout_s = float(peer_timeout_s)
        self._peer_heard = -float("inf")  # udpin: when the peer last wrote (monotonic) [s]
        self.address = LinkAddress.parse(url, name)
        self.mav = mavlink.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self.mav.robust_parsing = True
        self.stats = LinkStats()
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)  # bursts (the kernel may cap it)
        a = self.address
        if a.mode == "udpin":
            self.sock.bind((a.host, a.port))
            self.peer: tuple[str, int] | None = None
        else:
            self.peer = (socket.gethostbyname(a.host), a.port)
            self.sock.bind((_source_address(self.peer), 0))
        self.sock.setblocking(False)

    @property
    def local_address(self) -> tuple[str, int]:
        return self.sock.getsockname()

    def fileno(self) -> int:
        return self.sock.fileno()

    def recv(self, max_datagrams: int = 256) -> list:
        """Every message in the datagrams waiting (at most ``max_datagrams``), malformed ones dropped."""
        out = []
        for _ in range(max_datagrams):
            try:
                data, addr = self.sock.recvfrom(_MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # ICMP port unreachable from a vanished udpout peer, and the like
                self.stats.send_errors += 1
                continue
            udpin = self.address.mode == "udpin"
            if udpin:
                now = time.monotonic()
                if self.peer is not None and addr != self.peer and now - self._peer_heard <= self.peer_timeout_s:
                    self.stats.foreign += 1  # not our peer, which is still there
                    continue
            valid = 0
            try:
                msgs = self.mav.parse_buffer(data) or []
            except Exception:  # pymavlink raises a variety of errors on garbage
                msgs = [None]
            if self.mav.buf_len() > 0:  # a datagram holds whole frames: a partial one is garbage, not a prefix
                msgs.append(None)
            self.mav.buf = bytearray()
            self.mav.buf_index = 0
            self.mav.expected_length = mavlink.HEADER_LEN_V1 + 2
            for m in msgs:
                kind = "BAD_DATA" if m is None else m.get_type()
                if kind == "BAD_DATA" or m.get_msgId() < 0:
                    self.stats.bad_data += 1
                    continue
                self.stats.received += 1
                self.stats.by_type[kind] = self.stats.by_type.get(kind, 0) + 1
                out.append(m)
                valid += 1
            if udpin and valid:  # only a sender of CRC-valid MAVLink becomes (or stays) the peer: not a port scan
                self.peer, self._peer_heard = addr, now
        return out

    def send(self, msg) -> bool:
        """Pack ``msg`` (a pymavlink message) with this link's sequence and ids and send it to the peer."""
        if self.peer is None:
            return False
        try:
            self.sock.sendto(msg.pack(self.mav), self.peer)
        except OSError:
            self.stats.send_errors += 1
            return False
        self.mav.seq = (self.mav.seq + 1) % 256
        self.stats.sent += 1
        return True

    def close(self) -> None:
        self.sock.close()
