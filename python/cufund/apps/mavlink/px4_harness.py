"""PX4's side of the simulator contract, played from Python: what ``px4_sitl``'s ``simulator_mavlink`` does on
the wire (connect, heartbeat, SET_MESSAGE_INTERVAL for HIL_STATE_QUATERNION, read HIL_SENSOR / HIL_GPS, answer
with HIL_ACTUATOR_CONTROLS). For tests and benchmarks of :class:`~cufund.apps.mavlink.Px4SimulatorBridge`, since PX4
itself is not installed here; also a starting point for a custom flight stack in Python."""

from __future__ import annotations

import os
import select
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Px4Harness", "Px4Step"]

MAV_TYPE_QUADROTOR, MAV_AUTOPILOT_PX4 = 2, 12


@dataclass
class Px4Step:
    """What the simulator sent for one HIL_SENSOR period: instance 0's HIL_SENSOR (it closes the period) and
    whatever came before it since the previous one."""

    sensor: Any
    sensors: list[Any] = field(default_factory=list)
    """HIL_SENSOR messages of further sensor instances (``id`` 1, 2, ...)."""
    gps: list[Any] = field(default_factory=list)
    state: list[Any] = field(default_factory=list)
    """HIL_STATE_QUATERNION messages."""
    other: list[Any] = field(default_factory=list)


class Px4Harness:
    """A MAVLink peer acting as PX4 over raw byte I/O: ``write(bytes)`` and ``read(timeout) -> bytes | None``
    (b"" when the link closed). Use :meth:`tcp` (SITL) or :meth:`fd` (a serial line, e.g. a pty's master)."""

    def __init__(
        self,
        write: Callable[[bytes], None],
        read: Callable[[float], bytes | None],
        close: Callable[[], None],
        system_id: int = 1,
        component_id: int = 1,
    ) -> None:
        from pymavlink.dialects.v20 import common as mavlink

        self._write, self._read, self._close = write, read, close
        self.mav = mavlink.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self.mav.robust_parsing = True
        self._queue: list[Any] = []
        self.closed = False

    @classmethod
    def tcp(cls, host: str, port: int, timeout: float = 10.0) -> Px4Harness:
        """Connects like ``simulator_mavlink start -c PORT`` (retrying until ``timeout`` [s])."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                sock = socket.create_connection((host, port), timeout=max(deadline - time.monotonic(), 0.01))
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.02)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.settimeout(None)

        def read(t: float) -> bytes | None:
            ready, _, _ = select.select([sock], [], [], max(t, 0.0))
            if not ready:
                return None
            try:
                return sock.recv(65536)
            except OSError:
                return b""

        def close() -> None:  # an orderly leave: FIN, then what the simulator still sends is read, then close (a
            try:  # close with unread bytes would reset the connection, which the simulator reports as a failure)
                sock.shutdown(socket.SHUT_WR)
                end = time.monotonic() + 1.0
                while time.monotonic() < end:
                    ready, _, _ = select.select([sock], [], [], max(end - time.monotonic(), 0.0))
                    if not ready or not sock.recv(65536):
                        break
            except OSError:
                pass
            sock.close()

        return cls(sock.sendall, read, close)

    @classmethod
    def fd(cls, fd: int) -> Px4Harness:
        """Talks over a file descriptor (the master end of a pseudo-terminal standing in for a serial port)."""

        def read(t: float) -> bytes | None:
            ready, _, _ = select.select([fd], [], [], max(t, 0.0))
            if not ready:
                return None
            try:
                return os.read(fd, 65536)
            except OSError:
                return b""

        def write(data: bytes) -> None:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view) :]

        return cls(write, read, lambda: None)

    # -- sending ---------------------------------------------------------------------------------------------
    def send(self, msg: Any) -> None:
        self._write(msg.pack(self.mav))

    def heartbeat(self, armed: bool = False) -> None:
        self.send(self.mav.heartbeat_encode(MAV_TYPE_QUADROTOR, MAV_AUTOPILOT_PX4, 128 if armed else 0, 0, 0))

    def request_state(self, interval_us: float = 5000.0) -> None:
        """MAV_CMD_SET_MESSAGE_INTERVAL for HIL_STATE_QUATERNION, as simulator_mavlink sends at start."""
        self.send(self.mav.command_long_encode(0, 0, 511, 0, 115, interval_us, 0, 0, 0, 0, 0))

    def controls(self, u: Any, armed: bool = True, time_usec: int = 0) -> None:
        """HIL_ACTUATOR_CONTROLS with motor outputs ``u`` (up to 16), ``mode`` armed bit, lockstep flag."""
        values = [float(x) for x in u] + [0.0] * (16 - len(u))
        self.send(self.mav.hil_actuator_controls_encode(time_usec, values, (128 if armed else 0) | 1, 1))

    # -- receiving -------------------------------------------------------------------------------------------
    def poll(self, timeout: float) -> list[Any]:
        """Messages that arrive within ``timeout`` [s] (at least one read; returns early once something came)."""
        data = self._read(timeout)
        if data == b"":
            self.closed = True
            return []
        if data:
            self._queue.extend(self.mav.parse_buffer(data) or ())
        out, self._queue = self._queue, []
        return out

    def step(self, timeout: float = 10.0) -> Px4Step:
        """Reads until the next HIL_SENSOR of instance 0. Raises TimeoutError (nothing within ``timeout`` [s])
        or ConnectionError (the simulator closed the link)."""
        deadline = time.monotonic() + timeout
        sensors: list[Any] = []
        gps: list[Any] = []
        state: list[Any] = []
        other: list[Any] = []
        while True:
            while self._queue:
                msg = self._queue.pop(0)
                kind = msg.get_type()
                if kind == "HIL_SENSOR" and msg.id == 0:
                    return Px4Step(msg, sensors, gps, state, other)
                {"HIL_SENSOR": sensors, "HIL_GPS": gps, "HIL_STATE_QUATERNION": state}.get(kind, other).append(msg)
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"no HIL_SENSOR within {timeout} s")
            data = self._read(remaining)
            if data == b"":
                self.closed = True
                raise ConnectionError("the simulator closed the link")
            if data:
                self._queue.extend(self.mav.parse_buffer(data) or ())

    def close(self) -> None:
        self._close()
        self.closed = True
