"""MAVLink endpoint latency with real clients: MAVSDK (mavsdk_server + gRPC wrapper) and, in the same run, a bare
pymavlink socket (no mavsdk_server/gRPC hop), both on the same live vehicle at real time.

- Telemetry latency: from the wall-clock instant the simulation reached time t (recorded by a 1 kHz run listener)
  to the instant the client holds the ATTITUDE_QUATERNION stamped t (MAVSDK asked for 50 Hz).
- Command round trip: COMMAND_LONG arm then disarm on the ground (each through the commander at its next step),
  from the client's call to its COMMAND_ACK.

    .venv/bin/python benchmarks/bench_mavlink_latency.py [--seconds 10] [--commands 20]
"""

from __future__ import annotations

import argparse
import asyncio
import bisect
import socket
import statistics
import subprocess
import threading
import time
from pathlib import Path

import mavsdk_grpc as mavsdk
from pymavlink import mavutil

from cufund.apps.live import LiveRun
from cufund.apps.mavlink.vehicle_endpoint import VehicleEndpoint

M = mavutil.mavlink


def _free(kind: int) -> int:
    s = socket.socket(socket.AF_INET, kind)
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


class SimClock:
    """(sim t, wall) pairs from a run listener: the wall instant the simulation reached each t."""

    def __init__(self, live: LiveRun) -> None:
        self.t: list[float] = []
        self.wall: list[float] = []
        self.lock = threading.Lock()
        self.remove = live.add_listener(self._on, 1000.0)

    def _on(self, tel: dict) -> None:
        with self.lock:
            self.t.append(float(tel["t"]))
            self.wall.append(time.perf_counter())

    def wall_at(self, t: float) -> float | None:
        """The first recorded wall time at which the simulation had reached ``t`` (None if not yet)."""
        with self.lock:
            i = bisect.bisect_left(self.t, t - 1e-9)
            return self.wall[i] if i < len(self.wall) else None


def _summary(name: str, xs: list[float]) -> str:
    xs = sorted(xs)
    p95 = xs[min(len(xs) - 1, int(0.95 * len(xs)))]
    return (
        f"{name:<38} n={len(xs):4d}  median {statistics.median(xs) * 1e3:6.1f} ms  p95 {p95 * 1e3:6.1f} ms  "
        f"max {xs[-1] * 1e3:6.1f} ms"
    )


async def _mavsdk(grpc: int, clock: SimClock, seconds: float, commands: int) -> tuple[list[float], list[float]]:
    drone = mavsdk.System(mavsdk_server_address="127.0.0.1", port=grpc)
    await drone.connect()
    async for s in drone.core.connection_state():
        if s.is_connected:
            break
    await drone.telemetry.set_rate_attitude_quaternion(50.0)
    lat: list[float] = []
    end = time.perf_counter() + seconds
    async for q in drone.telemetry.attitude_quaternion():
        now = time.perf_counter()
        wall = clock.wall_at(q.timestamp_us * 1e-6)
        if wall is not None:
            lat.append(now - wall)
        if now > end:
            break
    rtt: list[float] = []
    for _ in range(commands):
        for call, armed in ((drone.action.arm, True), (drone.action.disarm, False)):
            t0 = time.perf_counter()
            await call()
            rtt.append(time.perf_counter() - t0)
            async for a in drone.telemetry.armed():  # MAVSDK refuses a disarm until it has seen the arming
                if a == armed:
                    break
    return lat[10:], rtt  # the first samples include the stream's start-up


def _pymavlink(port: int, clock: SimClock, seconds: float, commands: int) -> tuple[list[float], list[float]]:
    conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=254, dialect="common")
    conn.recv_match(type="HEARTBEAT", blocking=True, timeout=10)
    conn.mav.command_long_send(
        1, 1, M.MAV_CMD_SET_MESSAGE_INTERVAL, 0, M.MAVLINK_MSG_ID_ATTITUDE_QUATERNION, 20000, 0, 0, 0, 0, 0
    )
    lat: list[float] = []
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        m = conn.recv_match(type="ATTITUDE_QUATERNION", blocking=True, timeout=1)
        now = time.perf_counter()
        if m is not None:
            wall = clock.wall_at(m.time_boot_ms * 1e-3)
            if wall is not None:
                lat.append(now - wall)
    rtt: list[float] = []
    for _ in range(commands):
        for arm in (1, 0):
            t0 = time.perf_counter()
            conn.mav.command_long_send(1, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, arm, 0, 0, 0, 0, 0, 0)
            if conn.recv_match(type="COMMAND_ACK", blocking=True, timeout=5) is not None:
                rtt.append(time.perf_counter() - t0)
    conn.close()
    return lat[10:], rtt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=10.0, help="telemetry sampling per client [s]")
    ap.add_argument("--commands", type=int, default=20, help="arm/disarm pairs per client")
    ap.add_argument("--telemetry-hz", type=float, default=250.0, help="the live run's telemetry snapshot rate")
    args = ap.parse_args()
    api, gcs, grpc = _free(socket.SOCK_DGRAM), _free(socket.SOCK_DGRAM), _free(socket.SOCK_STREAM)
    server = subprocess.Popen(
        [str(Path(mavsdk.__file__).parent / "bin" / "mavsdk_server"), "-p", str(grpc), f"udpin://127.0.0.1:{api}"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    live = LiveRun("vehicle", speed=1.0, telemetry_hz=args.telemetry_hz)
    clock = SimClock(live)
    endpoint = VehicleEndpoint(live, [f"udpout:127.0.0.1:{api}", f"udpout:127.0.0.1:{gcs}"]).start()
    try:
        results = {}
        results["pymavlink"] = _pymavlink(gcs, clock, args.seconds, args.commands)
        results["MAVSDK"] = asyncio.run(
            asyncio.wait_for(_mavsdk(grpc, clock, args.seconds, args.commands), args.seconds + 60 * args.commands)
        )
        tel = live.telemetry()
        print(
            f"vehicle scenario at speed 1 (measured real-time factor {tel['real_time_factor']:.2f}); "
            f"telemetry snapshots {args.telemetry_hz:g} Hz, ATTITUDE_QUATERNION at 50 Hz"
        )
        for name, (lat, rtt) in results.items():
            print(_summary(f"{name}: sim state -> client (telemetry)", lat))
            print(_summary(f"{name}: COMMAND_LONG -> COMMAND_ACK", rtt))
        m_lat, p_lat = statistics.median(results["MAVSDK"][0]), statistics.median(results["pymavlink"][0])
        m_rtt, p_rtt = statistics.median(results["MAVSDK"][1]), statistics.median(results["pymavlink"][1])
        print(
            f"MAVSDK / bare pymavlink: telemetry latency x{m_lat / p_lat:.2f}, command round trip "
            f"x{m_rtt / p_rtt:.2f} (MAVSDK adds the mavsdk_server + gRPC hop; the pymavlink client shares this "
            "process's GIL with the simulation)"
        )
    finally:
        endpoint.close()
        clock.remove()
        live.stop()
        server.terminate()
        try:
            server.wait(5)
        except subprocess.TimeoutExpired:
            server.kill()


if __name__ == "__main__":
    main()
