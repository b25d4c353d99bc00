"""Byte links between cufund and PX4: the SITL TCP server (PX4 connects to 4560 + instance) and a serial port
for HITL (pyserial). Both: ``send(data)``, ``recv(timeout) -> bytes | None`` (None: nothing arrived within the
timeout; ``b""``: the peer closed the link; :class:`LinkClosed` raised: the link failed, e.g. the peer reset it),
``close()``."""

from __future__ import annotations

import logging
import os
import select
import socket
import struct
import time
from typing import Protocol

__all__ = ["PX4_SITL_BASE_PORT", "GcsForward", "Link", "LinkClosed", "SerialLink", "TcpServerLink"]

PX4_SITL_BASE_PORT = 4560  #: PX4's simulator_mavlink connects to TCP 4560 + instance
_TIMEVAL = struct.Struct("@ll")  # struct timeval: seconds, microseconds (C longs)
#: How long a lockstep wait polls the socket before blocking [s]: PX4 answers a HIL_SENSOR within tens of
#: microseconds, and a blocked thread's wake-up on another CPU costs about as much again. Only when this process
#: may run on more than one CPU: pinned to PX4's CPU (``--cpu``), polling would only delay PX4.
_SPIN_S = 60e-6
_DRAIN_S = 0.25  #: at most this long [s] a closing link reads PX4's last bytes while PX4 reads ours
#: What a second simulator client reads before its connection is closed (one PX4 per bridge).
BUSY_MESSAGE = b"cufund px4-sim: already serving a PX4 connection; this one is refused\n"
_log = logging.getLogger("cufund.px4_sim")


class LinkClosed(ConnectionError):
    """The link failed (the peer reset it, a send failed); the message says why."""


class Link(Protocol):
    def send(self, data: bytes) -> None: ...

    def recv(self, timeout: float) -> bytes | None: ...

    def close(self) -> None: ...


class TcpServerLink:
    """Listens on ``host:port`` (127.0.0.1 unless told otherwise; port 0 picks a free one, see :attr:`port`) and
    serves one PX4 connection at a time, with TCP_NODELAY as Gazebo's plugin does. Another client connecting
    meanwhile is refused by :meth:`refuse_pending` (:data:`BUSY_MESSAGE`, a log line, counted in ``refused``)
    instead of waiting unanswered in the listen backlog."""

    def __init__(self, host: str = "127.0.0.1", port: int = PX4_SITL_BASE_PORT) -> None:
        if not isinstance(host, str) or not host:
            raise ValueError(f"host must be an address string like 127.0.0.1, got {host!r}")
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise ValueError(f"port must be an integer in [0, 65535], got {port!r}")
        self._server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._server.bind((host, port))
        except OSError as e:
            self._server.close()
            raise OSError(f"cannot listen on {host}:{port}: {e.strerror or e}") from None
        self._server.listen(1)
        self.host, self.port = host, self._server.getsockname()[1]
        self._conn: socket.socket | None = None
        self._rcvtimeo = 0.0  # the connection's SO_RCVTIMEO [s]
        self.spin_s = 0.0  # how long recv polls before blocking [s]: _SPIN_S once connected, unless pinned
        self.refused = 0

    @property
    def connected(self) -> bool:
        return self._conn is not None

    def accept(self, timeout: float | None) -> bool:
        """Waits up to ``timeout`` [s] (None: forever) for PX4 to connect. True once connected."""
        if self._conn is not None:
            return True
        ready, _, _ = select.select([self._server], [], [], timeout)
        if not ready:
            return False
        conn, _ = self._server.accept()
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        conn.settimeout(None)  # blocking: Python neither polls before each call nor sets O_NONBLOCK
        self._conn = conn
        self._set_rcvtimeo(1.0)
        self.spin_s = _SPIN_S if len(os.sched_getaffinity(0)) > 1 else 0.0  # the CPUs allowed now (--cpu pins)
        return True

    def refuse_pending(self) -> int:
        """While connected: accepts and closes every other client waiting (after :data:`BUSY_MESSAGE` and a
        log line), without waiting. Returns how many were refused."""
        n = 0
        while self._conn is not None:
            ready, _, _ = select.select([self._server], [], [], 0.0)
            if not ready:
                break
            try:
                other, addr = self._server.accept()
            except OSError:
                break
            try:
                other.settimeout(0.5)
                other.sendall(BUSY_MESSAGE)
                other.shutdown(socket.SHUT_WR)
            except OSError:
                pass
            finally:
                other.close()
            n += 1
            _log.warning("px4-sim: refused a second simulator connection from %s:%d (already serving one)", *addr)
        self.refused += n
        return n

    def send(self, data: bytes) -> None:
        if self._conn is None:
            raise LinkClosed("no PX4 connection")
        try:
            self._conn.sendall(data)
        except OSError as e:
            self._drop()
            raise LinkClosed(f"PX4 connection lost: {e.strerror or e}") from None

    def recv(self, timeout: float) -> bytes | None:
        """What has arrived, waiting up to ``timeout`` [s] (to within 1 ms) for the first byte: one ``recv``
        system call. The wait is the socket's receive timeout (SO_RCVTIMEO), set only when ``timeout`` changes by
        more than 1 ms (no poll/select per call, and no setsockopt per period for a wait that restarts at the same
        length); a zero timeout reads what is waiting without blocking."""
        conn = self._conn
        if conn is None:
            return b""
        data: bytes | None
        try:
            if timeout <= 0.0:
                data = conn.recv(65536, socket.MSG_DONTWAIT)
            else:
                data = self._poll(conn) if self.spin_s > 0.0 else None
                if data is None:
                    if abs(timeout - self._rcvtimeo) > 1e-3:
                        self._set_rcvtimeo(timeout)
                    data = conn.recv(65536)
        except BlockingIOError:  # EAGAIN: nothing within the timeout (or nothing waiting)
            return None
        except OSError as e:  # ECONNRESET and the like: not an orderly close
            self._drop()
            raise LinkClosed(f"PX4 connection failed: {e.strerror or e}") from None
        if not data:
            self._drop()
        return data

    def _poll(self, conn: socket.socket) -> bytes | None:
        """Non-blocking reads for up to :attr:`spin_s`; None if nothing arrived."""
        deadline = time.perf_counter() + self.spin_s
        while True:
            try:
                return conn.recv(65536, socket.MSG_DONTWAIT)
            except BlockingIOError:
                if time.perf_counter() >= deadline:
                    return None

    def _set_rcvtimeo(self, timeout: float) -> None:
        usec = max(round(timeout * 1e6), 1)  # a zero timeval would mean "block forever"
        assert self._conn is not None
        self._conn.setsockopt(socket.SOL_SOCKET, socket.SO_RCVTIMEO, _TIMEVAL.pack(usec // 1_000_000, usec % 1_000_000))
        self._rcvtimeo = usec * 1e-6

    def disconnect(self) -> None:
        """Closes the PX4 connection (after PX4 has read what was sent); the server keeps listening for the next
        one."""
        self._drop(graceful=True)

    def _drop(self, graceful: bool = False) -> None:
        conn, self._conn = self._conn, None
        if conn is None:
            return
        if graceful:  # closing with PX4's bytes unread would send a reset, and PX4 would lose what it has not read
            try:
                conn.shutdown(socket.SHUT_WR)
                conn.settimeout(_DRAIN_S)
                end = time.perf_counter() + _DRAIN_S
                while conn.recv(65536) and time.perf_counter() < end:
                    pass
            except OSError:
                pass
        conn.close()

    def close(self) -> None:
        self._drop(graceful=True)
        self._server.close()


class SerialLink:
    """A serial port (HITL: the flight controller's USB or TELEM port) through pyserial, 8N1, no flow control."""

    def __init__(self, device: str, baud: int = 921600) -> None:
        import serial

        if not isinstance(device, str) or not device:
            raise ValueError(f"device must be a serial port path like /dev/ttyACM0, got {device!r}")
        if isinstance(baud, bool) or not isinstance(baud, int) or baud <= 0:
            raise ValueError(f"baud must be a positive integer, got {baud!r}")
        try:
            self._port = serial.Serial(device, baud, timeout=0, write_timeout=1.0)
        except (serial.SerialException, OSError) as e:
            raise OSError(f"cannot open serial port {device}: {e}") from None
        self.device, self.baud = device, baud
        self._fd = self._port.fileno()
        os.set_blocking(self._fd, False)  # pyserial's own default on POSIX; recv relies on it

    connected = True

    def send(self, data: bytes) -> None:
        try:
            self._port.write(data)
        except OSError as e:  # serial.SerialException and its timeout are OSErrors
            raise LinkClosed(f"serial port {self.device}: {e}") from None

    def recv(self, timeout: float) -> bytes | None:
        try:  # pyserial keeps the descriptor non-blocking: a zero timeout reads without a select
            if timeout > 0.0:
                ready, _, _ = select.select([self._fd], [], [], timeout)
                if not ready:
                    return None
            return os.read(self._fd, 65536) or None
        except BlockingIOError:
            return None
        except OSError as e:
            raise LinkClosed(f"serial port {self.device}: {e.strerror or e}") from None

    def close(self) -> None:
        self._port.close()


class GcsForward:
    """HITL's window for ground stations, as Gazebo's plugin has: the flight controller's MAVLink (read off the
    serial line) goes out over UDP to ``host:port`` (QGroundControl listens on 14550), and what comes back to the
    sending socket goes to the serial line."""

    def __init__(self, host: str = "127.0.0.1", port: int = 14550) -> None:
        if not isinstance(host, str) or not host:
            raise ValueError(f"host must be an address string like 127.0.0.1, got {host!r}")
        if isinstance(port, bool) or not isinstance(port, int) or not 1 <= port <= 65535:
            raise ValueError(f"port must be an integer in [1, 65535], got {port!r}")
        self.address = (host, port)
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self._sock.bind(("127.0.0.1" if host in ("127.0.0.1", "localhost") else "0.0.0.0", 0))
        self._sock.setblocking(False)

    def send(self, data: bytes) -> None:
        try:
            self._sock.sendto(data, self.address)
        except OSError:  # nobody listening (ICMP unreachable) or a full buffer: a GCS is optional
            pass

    def poll(self) -> bytes:
        """Everything the ground station sent since the last poll (b"" when nothing)."""
        chunks = []
        while True:
            try:
                chunks.append(self._sock.recv(65536))
            except OSError:  # BlockingIOError when drained; ConnectionRefused after an unanswered send
                return b"".join(chunks)

    def close(self) -> None:
        self._sock.close()
