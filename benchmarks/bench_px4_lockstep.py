"""Lockstep throughput of cufund as PX4's simulator: HIL_SENSOR -> HIL_ACTUATOR_CONTROLS round trips per second.

PX4 needs 250 round trips/s to run in real time; the target (issue 15) is >= 5000/s so PX4 never waits on cufund.
Three peers, the same scenario (iris, noisy IMU/mag/baro/GPS models, 1 kHz physics):
  in-process   the controls are handed back without a socket (cufund's own cost per period: sensors, physics,
               encoding, parsing)
  tcp, C-speed a separate process answers each HIL_SENSOR with pre-packed controls (what px4_sitl's C side costs)
  tcp, harness a separate process running the pymavlink harness the tests use (parses everything, packs replies)
and, as the transport's ceiling on this machine, a bare TCP ping-pong of the same sizes with no simulation.
Run: `.venv/bin/python benchmarks/bench_px4_lockstep.py [seconds of simulated time, default 20]`.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import socket
import sys
import time

from cufund.mavlink.px4_harness import Px4Harness
from cufund.mavlink.px4_links import TcpServerLink
from cufund.mavlink.px4_sim import Px4BridgeParams, Px4SimulatorBridge
from cufund.presets import iris
from cufund.scenario import ScenarioConfig

U_HOVER = (iris().hover_rotor_speed - 100.0) / 1000.0
PARAMS = Px4BridgeParams(speed=None, wait_first_controls=True)


def _config() -> ScenarioConfig:
    return ScenarioConfig.from_dict({"name": "bench_px4", "vehicle": "iris", "seed": 1, "sensors": {
        "imu": "icm42688p", "magnetometer": "magnetometer", "barometer": "ms5611", "gps": "ublox_m8n"}})


def _controls_bytes() -> bytes:
    from pymavlink.dialects.v20 import common as mavlink

    mav = mavlink.MAVLink(None, 1, 1)
    return mav.hil_actuator_controls_encode(0, [U_HOVER] * 4 + [0.0] * 12, 129, 1).pack(mav)


class _Loopback:
    """A link whose peer answers every HIL_SENSOR at once, without a socket."""

    def __init__(self) -> None:
        self.reply, self.pending = _controls_bytes(), b""

    def send(self, data: bytes) -> None:
        self.pending += self.reply

    def recv(self, timeout: float) -> bytes | None:
        out, self.pending = self.pending, b""
        return out or None

    def close(self) -> None:
        pass


def _c_speed_peer(port: int) -> None:
    """Answers each write of the bridge (each ends with a HIL_SENSOR) with pre-packed controls, no parsing."""
    reply = _controls_bytes()
    sock = socket.create_connection(("127.0.0.1", port))
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    while True:
        data = sock.recv(65536)
        if not data:
            break
        sock.sendall(reply)
    sock.close()


def _echo_peer(port: int) -> None:
    reply = _controls_bytes()
    sock = socket.create_connection(("127.0.0.1", port))
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    while sock.recv(65536):
        sock.sendall(reply)
    sock.close()


def _ping_pong(seconds: float) -> float:
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    proc = mp.get_context("spawn").Process(target=_echo_peer, args=(server.getsockname()[1],), daemon=True)
    proc.start()
    conn, _ = server.accept()
    conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    payload, n = b"\xfd" * 74, int(seconds * 250)
    t0 = time.perf_counter()
    for _ in range(n):
        conn.sendall(payload)
        conn.recv(65536)
    rate = n / (time.perf_counter() - t0)
    conn.close()
    server.close()
    proc.join(10.0)
    return rate


def _harness_peer(port: int) -> None:
    px4 = Px4Harness.tcp("127.0.0.1", port)
    px4.heartbeat()
    while True:
        try:
            s = px4.step(timeout=30.0)
        except (ConnectionError, TimeoutError):
            break
        px4.controls([U_HOVER] * 4, time_usec=s.sensor.time_usec)
    px4.close()


def _run(bridge: Px4SimulatorBridge, seconds: float) -> tuple[float, float]:
    """(round trips per wall second, per CPU second of this process: cufund's own cost, whatever the load)."""
    bridge.simulator.vehicle.hover([0.0, 0.0, 10.0])
    t0, c0 = time.perf_counter(), time.process_time()
    bridge.run(duration=seconds, connect_timeout=30.0)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return bridge.stats["controls"] / wall, bridge.stats["controls"] / cpu


def main() -> None:
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 20.0
    print(f"PX4 lockstep round trips per second over {seconds:g} s simulated ({int(seconds * 250)} periods); "
          f"real time needs 250/s, target >= 5000/s")
    results = {}
    results["in-process"] = _run(Px4SimulatorBridge(_config(), _Loopback(), PARAMS), seconds)
    for name, peer in (("tcp, C-speed peer", _c_speed_peer), ("tcp, pymavlink harness", _harness_peer)):
        bridge = Px4SimulatorBridge(_config(), TcpServerLink("127.0.0.1", 0), PARAMS)
        proc = mp.get_context("spawn").Process(target=peer, args=(bridge.port_number,), daemon=True)
        proc.start()
        try:
            results[name] = _run(bridge, seconds)
        finally:
            bridge.close()
            proc.join(10.0)
            if proc.is_alive():
                proc.kill()
    results["tcp ping-pong, no sim"] = (_ping_pong(seconds), float("nan"))
    print(f"  {'peer':<24} {'per wall s':>10} {'x real time':>12} {'x target':>9} {'per cufund CPU s':>17}")
    for name, (rate, cpu_rate) in results.items():
        print(f"  {name:<24} {rate:10.0f} {rate / 250:12.1f} {rate / 5000:9.2f} {cpu_rate:17.0f}")
    print(f"  (load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores: wall rates fall with other work)")


if __name__ == "__main__":
    main()
