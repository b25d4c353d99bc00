"""Shared helpers of the MAVLink endpoint tests: free ports, a live vehicle behind a VehicleEndpoint, and a
pymavlink ground station that waits with timeouts (a hang is a failure, never a stuck test)."""

from __future__ import annotations

import contextlib
import math
import socket
import time
from collections.abc import Callable, Iterator
from typing import Any

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink2

SPEED = 3.0
"""Simulation speed of the tests' live runs (the vehicle scenario runs ~3x real time on 2 loaded cores)."""


def free_port(kind: int = socket.SOCK_DGRAM) -> int:
    s = socket.socket(socket.AF_INET, kind)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class Gcs:
    """A pymavlink ground station listening on 127.0.0.1:port (the endpoint's udpout target)."""

    def __init__(self, port: int, system_id: int = 255) -> None:
        self.conn = mavutil.mavlink_connection(
            f"udpin:127.0.0.1:{port}", source_system=system_id, source_component=190, dialect="common"
        )
        # MAVLink 2 whatever MAVLINK20 says (MAVLink 1 drops extension fields such as mission_type)
        self.conn.mav = mavlink2.MAVLink(self.conn, srcSystem=system_id, srcComponent=190)
        self.conn.mav.robust_parsing = True
        self.conn.port.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)  # floods of acks while we send
        self.mav = self.conn.mav

    def recv(
        self, types: str | list[str] | None = None, timeout: float = 5.0, cond: Callable[[Any], bool] | None = None
    ) -> Any:
        """The next message of ``types`` satisfying ``cond``; AssertionError after ``timeout`` s."""
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            m = self.conn.recv_match(type=types, blocking=True, timeout=min(0.2, max(end - time.monotonic(), 0.01)))
            if m is not None and m.get_type() != "BAD_DATA" and (cond is None or cond(m)):
                return m
        raise AssertionError(f"no {types} within {timeout} s")

    def drain(self) -> None:
        while self.conn.recv_match(blocking=False) is not None:
            pass

    def heartbeat(self) -> None:
        self.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)

    def command(self, command: int, *params: float, timeout: float = 5.0) -> Any:
        """COMMAND_LONG to the vehicle; its COMMAND_ACK."""
        p = list(params) + [0.0] * (7 - len(params))
        self.mav.command_long_send(1, 1, command, 0, *p)
        return self.recv("COMMAND_ACK", timeout, cond=lambda m: m.command == command)

    def wait(self, types: str | list[str], cond: Callable[[Any], bool], timeout: float, keepalive: bool = True) -> Any:
        """Waits for a message satisfying ``cond``, sending a heartbeat every 0.5 s (a live link)."""
        end = time.monotonic() + timeout
        next_hb = 0.0
        while time.monotonic() < end:
            if keepalive and time.monotonic() >= next_hb:
                self.heartbeat()
                next_hb = time.monotonic() + 0.5
            with contextlib.suppress(AssertionError):
                return self.recv(types, min(0.5, max(end - time.monotonic(), 0.01)), cond)
        raise AssertionError(f"{types}: condition not met within {timeout} s")

    def close(self) -> None:
        self.conn.close()


@contextlib.contextmanager
def vehicle(
    speed: float = SPEED,
    links: int = 1,
    extra_links: tuple[str, ...] | list[str] = (),
    scenario: Any = "vehicle",
    **endpoint_kw: Any,
) -> Iterator[tuple[Any, Any, list[Gcs]]]:
    """A live run of ``scenario`` (default: the ``vehicle`` scenario) behind a VehicleEndpoint with ``links``
    udpout links, each to its own Gcs, and ``extra_links`` (URLs) to other clients."""
    from cufund.apps.live import LiveRun
    from cufund.apps.mavlink.vehicle_endpoint import VehicleEndpoint

    ports = [free_port() for _ in range(links)]
    gcss = [Gcs(p) for p in ports]
    live = LiveRun(scenario, speed=speed)
    endpoint = None
    try:
        urls = [f"udpout:127.0.0.1:{p}" for p in ports] + list(extra_links)
        endpoint = VehicleEndpoint(live, urls, **endpoint_kw).start()
        for g in gcss:
            g.recv("HEARTBEAT", 30.0)  # CI once saw none within 10 s (cause not found; 1 Hz, first at once here)
        yield live, endpoint, gcss
    finally:
        if endpoint is not None:
            endpoint.close()
        live.stop()
        for g in gcss:
            g.close()


OPEN_FIELD = {
    "name": "open_field",
    "vehicle": "cu_astro",
    "planner": {"kind": "commander"},
    "controller": "pid",
    "start_p_W": [0.0, 0.0, 0.0],
    "duration": 600.0,
}
"""A commander's vehicle with nothing to hit (the vehicle scenario's arena is 12 m x 8 m with frames in it): for
tests whose flight distance depends on wall-clock timing."""


def relative_alt_m(m: Any) -> float:
    return m.relative_alt / 1000.0


NAN = math.nan


def px4_sim_cli(duration_s: float) -> tuple[Any, dict, int]:
    """``cufund px4-sim square_sensors`` (Iris, as fast as PX4 answers) in a thread, serving SITL on a free port
    above 4560 (the port stands for the instance number). Returns (the started thread, a dict that gets its exit
    code under "exit", the port)."""
    import threading

    from cufund.apps.cli import main

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    argv = ["px4-sim", "square_sensors", "--instance", str(port - 4560), "--speed", "max",
            "--duration", str(duration_s), "--set", "vehicle=iris", "--connect-timeout", "20"]  # fmt: skip
    code: dict = {}
    thread = threading.Thread(target=lambda: code.setdefault("exit", main(argv)), daemon=True)
    thread.start()
    return thread, code, port
