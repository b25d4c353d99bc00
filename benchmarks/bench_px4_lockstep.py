"""Lockstep throughput of cufund as PX4's simulator: HIL_SENSOR -> HIL_ACTUATOR_CONTROLS round trips per second.

PX4 needs 250 round trips/s to run in real time; the target (issue 15) is >= 5000/s so PX4 never waits on cufund.
Three peers, the same scenario (iris, noisy IMU/mag/baro/GPS models at PX4's rates, one physics step per
HIL_SENSOR period):
  in-process   the controls are handed back without a socket (cufund's own cost per period: sensors, physics,
               encoding, parsing)
  tcp, C-speed a separate process with a struct codec (what px4_sitl's C side costs): frames and CRC-checks the
               stream, decodes each HIL_SENSOR, answers instance 0's with controls stamped with its time; once
               where the OS places the two processes, once with both pinned to one CPU (``--cpu`` / ``taskset``)
  tcp, harness a separate process running the pymavlink harness the tests use (parses everything, packs replies)
and, as the transport's ceiling on this machine, a bare TCP ping-pong of the same sizes with no simulation.
Per round trip it prints wall, cufund's CPU and the peer's CPU [us]: wall minus the two CPUs is the hand-overs
(wake-ups, the other process's scheduling). Clocks start once the peer has connected (its start-up is printed).
Run: `.venv/bin/python benchmarks/bench_px4_lockstep.py [seconds of simulated time, default 20]`.
"""

from __future__ import annotations

import math
import multiprocessing as mp
import os
import socket
import sys
import time
from typing import Any

from cufund.apps.mavlink.px4_harness import Px4Harness
from cufund.apps.mavlink.px4_links import TcpServerLink
from cufund.apps.mavlink.px4_sim import Px4BridgeParams, Px4SimulatorBridge
from cufund.scenarios import ScenarioConfig
from cufund.vehicle.presets import iris

U_HOVER = (iris().hover_rotor_speed - 100.0) / 1000.0
PARAMS = Px4BridgeParams(speed=None, wait_first_controls=True)


def _config() -> ScenarioConfig:
    return ScenarioConfig.from_dict(
        {
            "name": "bench_px4",
            "vehicle": "iris",
            "seed": 1,
            "sensors": {"imu": "icm42688p", "magnetometer": "magnetometer", "barometer": "ms5611", "gps": "ublox_m8n"},
        }
    )


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


def _c_speed_peer(port: int, cpu_s: Any = None) -> None:
    """PX4's C side in miniature, with a struct codec: frames the byte stream, checks each CRC, decodes every
    HIL_SENSOR whole and answers each of instance 0 with HIL_ACTUATOR_CONTROLS stamped with its time (sequence
    numbered, CRC'd)."""
    import struct

    from fastcrc.crc16 import mcrf4xx
    from pymavlink.dialects.v20 import common as mavlink

    extra = {
        m.id: m.crc_extra
        for m in (
            mavlink.MAVLink_heartbeat_message,
            mavlink.MAVLink_hil_sensor_message,
            mavlink.MAVLink_hil_gps_message,
            mavlink.MAVLink_command_ack_message,
            mavlink.MAVLink_hil_state_quaternion_message,
        )
    }
    hil_sensor, ctl = mavlink.MAVLink_hil_sensor_message, mavlink.MAVLink_hil_actuator_controls_message
    header, u64 = struct.Struct("<BBBBBBBHB"), struct.Struct("<Q")
    sensor_unpack, sensor_size = hil_sensor.unpacker.unpack, hil_sensor.unpacker.size
    zeros = bytes(sensor_size)
    controls_tail = struct.pack("<Q16fB", 1, *([U_HOVER] * 4 + [0.0] * 12), 129)
    sock = socket.create_connection(("127.0.0.1", port))
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    c0 = time.process_time()
    buf, seq = b"", 0
    while True:
        data = sock.recv(65536)
        if not data:
            break
        buf += data
        i, out = 0, []
        while True:
            i = buf.find(b"\xfd", i)
            if i < 0 or len(buf) - i < 12 or len(buf) - i < 12 + buf[i + 1]:
                break
            n = buf[i + 1]
            msg_id = buf[i + 7] | buf[i + 8] << 8 | buf[i + 9] << 16
            end = i + 10 + n
            if (
                msg_id not in extra
                or mcrf4xx(bytes((extra[msg_id],)), mcrf4xx(buf[i + 1 : end])) != buf[end] | buf[end + 1] << 8
            ):
                i += 1
                continue
            if msg_id == hil_sensor.id:  # decoded whole, as PX4's simulator_mavlink does (trailing zeros restored)
                payload = buf[i + 10 : end]
                fields = sensor_unpack(payload + zeros[n:] if n < sensor_size else payload)
                if fields[-1] != 0:  # answered for the primary IMU (id 0) only
                    i = end + 2
                    continue
                body = (
                    header.pack(0xFD, ctl.unpacker.size, 0, 0, seq, 1, 1, ctl.id, 0)
                    + u64.pack(fields[0])
                    + controls_tail
                )
                out.append(body + struct.pack("<H", mcrf4xx(bytes((ctl.crc_extra,)), mcrf4xx(body[1:]))))
                seq = (seq + 1) & 0xFF
            i = end + 2
        buf = buf[i:] if i >= 0 else b""
        if out:
            sock.sendall(b"".join(out))
    sock.close()
    if cpu_s is not None:
        cpu_s.value = time.process_time() - c0


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


def _harness_peer(port: int, cpu_s: Any = None) -> None:
    px4 = Px4Harness.tcp("127.0.0.1", port)
    c0 = time.process_time()
    px4.heartbeat()
    while True:
        try:
            s = px4.step(timeout=30.0)
        except (ConnectionError, TimeoutError):
            break
        px4.controls([U_HOVER] * 4, time_usec=s.sensor.time_usec)
    px4.close()
    if cpu_s is not None:
        cpu_s.value = time.process_time() - c0


def _run(bridge: Px4SimulatorBridge, seconds: float) -> tuple[float, float, float]:
    """(round trips per wall second, per CPU second of this process: cufund's own cost, whatever the load; seconds
    the peer took to start and connect). The clocks start once the peer is connected: a peer process's start-up
    (a Python interpreter importing pymavlink, about 0.5 s) is not a round trip's cost and, over a 10 s run, used
    to add ~200 us to each."""
    bridge.simulator.vehicle.hover([0.0, 0.0, 10.0])
    t_connect = 0.0
    accept = getattr(bridge.link, "accept", None)
    if accept is not None:
        t = time.perf_counter()
        if not accept(30.0):
            raise TimeoutError("the peer did not connect")
        t_connect = time.perf_counter() - t
    t0, c0 = time.perf_counter(), time.process_time()
    bridge.run(duration=seconds, connect_timeout=30.0)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return bridge.stats["controls"] / wall, bridge.stats["controls"] / cpu, t_connect


def _tcp(peer, seconds: float, cpu: int | None = None) -> tuple[float, float, float, float]:
    """``_run`` over TCP against ``peer`` run in a separate process, plus the peer's CPU seconds per round trip
    (from its connection on). ``cpu``: both processes pinned to that CPU (lockstep is serial: on
    one CPU neither side waits for the other to be woken on another)."""
    mask = os.sched_getaffinity(0)
    if cpu is not None:
        os.sched_setaffinity(0, {cpu})  # the spawned peer inherits it
    try:
        ctx = mp.get_context("spawn")
        bridge = Px4SimulatorBridge(_config(), TcpServerLink("127.0.0.1", 0), PARAMS)
        peer_cpu = ctx.Value("d", math.nan)
        proc = ctx.Process(target=peer, args=(bridge.port_number, peer_cpu), daemon=True)
        proc.start()
        try:
            rate, cpu_rate, t_connect = _run(bridge, seconds)
        finally:
            bridge.close()
            proc.join(10.0)
            if proc.is_alive():
                proc.kill()
        return rate, cpu_rate, t_connect, peer_cpu.value / max(bridge.stats["controls"], 1)
    finally:
        os.sched_setaffinity(0, mask)


def main() -> None:
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 20.0
    print(
        f"PX4 lockstep round trips per second over {seconds:g} s simulated ({int(seconds * 250)} periods); "
        f"real time needs 250/s, target >= 5000/s"
    )
    load0 = os.getloadavg()[0]
    results = {}
    results["in-process"] = (*_run(Px4SimulatorBridge(_config(), _Loopback(), PARAMS), seconds), math.nan)
    one_cpu = max(os.sched_getaffinity(0))
    for name, peer, cpu in (
        ("tcp, C-speed peer", _c_speed_peer, None),
        ("tcp, C-speed, one CPU", _c_speed_peer, one_cpu),
        ("tcp, pymavlink harness", _harness_peer, None),
    ):
        results[name] = _tcp(peer, seconds, cpu)
    results["tcp ping-pong, no sim"] = (_ping_pong(seconds), math.nan, math.nan, math.nan)
    print(
        f"  {'peer':<24} {'per wall s':>10} {'x real time':>11} {'x target':>8} {'per cufund CPU s':>16} "
        f"{'us/trip: wall':>13} {'cufund CPU':>10} {'peer CPU':>8} {'peer start s':>12}"
    )
    for name, (rate, cpu_rate, t_connect, peer_cpu) in results.items():
        print(
            f"  {name:<24} {rate:10.0f} {rate / 250:11.1f} {rate / 5000:8.2f} {cpu_rate:16.0f} {1e6 / rate:13.0f} "
            f"{1e6 / cpu_rate:10.0f} {peer_cpu * 1e6:8.0f} {t_connect:12.2f}"
        )
    print(
        f"  (load average {load0:.1f} at the start, {os.getloadavg()[0]:.1f} at the end, on {os.cpu_count()} cores: "
        f"wall rates fall with other work; per CPU s is cufund's own cost. Clocks start once the peer is "
        f"connected. 'one CPU': cufund and the peer pinned to CPU {one_cpu}, as "
        f"`cufund px4-sim --cpu {one_cpu}` with `taskset -c {one_cpu} px4 ...` would be)"
    )


if __name__ == "__main__":
    main()
