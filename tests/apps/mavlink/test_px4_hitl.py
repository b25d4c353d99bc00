"""HITL: the same HIL messages over a serial port (pyserial), lockstep off, checked over a pseudo-terminal pair
(``os.openpty``): the bridge opens the slave as its serial port, a PX4-side harness talks on the master."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import threading
from contextlib import contextmanager

import numpy as np
import pytest

from cufund.apps.mavlink.px4_harness import Px4Harness
from cufund.apps.mavlink.px4_links import GcsForward, SerialLink
from cufund.apps.mavlink.px4_sim import Px4BridgeParams, Px4SimulatorBridge
from cufund.scenarios import ScenarioConfig
from cufund.vehicle.presets import iris

U_HOVER = (iris().hover_rotor_speed - 100.0) / 1000.0
IDEAL = {"imu": "ideal_imu", "magnetometer": "magnetometer", "barometer": "ideal_barometer", "gps": "ideal_gps"}


@contextmanager
def _pty():
    master, slave = os.openpty()
    try:
        yield master, os.ttyname(slave)
    finally:
        os.close(slave)
        os.close(master)


@contextmanager
def _hitl(duration, hover_at=None, speed=4.0, gcs=None):
    with _pty() as (master, device):
        cfg = ScenarioConfig.from_dict({"name": "hitl", "vehicle": "iris", "seed": 2, "sensors": IDEAL})
        bridge = Px4SimulatorBridge(
            cfg, SerialLink(device, 921600), Px4BridgeParams(lockstep=False, speed=speed), gcs=gcs
        )
        if hover_at is not None:
            bridge.simulator.vehicle.hover(np.asarray(hover_at, dtype=float))
        outcome: dict = {}

        def run():
            try:
                outcome["result"] = bridge.run(duration=duration)
            except BaseException as e:
                outcome["error"] = e

        thread = threading.Thread(target=run, daemon=True)
        thread.start()
        px4 = Px4Harness.fd(master)
        try:
            yield bridge, px4, outcome, thread
        finally:
            while thread.is_alive():  # keep the line drained so the bridge never blocks on a full pty
                px4.poll(0.05)
            thread.join(10.0)
            bridge.close()
            if "error" in outcome:
                raise outcome["error"]


def test_hitl_streams_without_waiting_for_controls():
    with _hitl(duration=0.6) as (bridge, px4, outcome, _):
        steps = [px4.step(timeout=5.0) for _ in range(100)]  # nobody answers: lockstep is off
        stamps = [s.sensor.time_usec for s in steps]
        assert stamps == list(range(4000, 404_000, 4000))
        assert sum(len(s.gps) for s in steps[:-1]) == 2  # 5 Hz: measured at 0 and 0.2 s
        np.testing.assert_allclose(np.mean([s.sensor.zacc for s in steps]), -9.80665, atol=0.01)
        assert all(s.sensor.fields_updated & 0x3F == 0x3F for s in steps)
    assert outcome["result"].message == "duration elapsed"
    assert bridge.stats["controls"] == 0 and bridge.stats["controls_timeouts"] == 0


def test_hitl_controls_take_effect_and_go_stale():
    # real time, as HITL runs: the answers may lag the stream by up to stale_controls_s (0.2 s) of wall time
    with _hitl(duration=1.6, hover_at=(0.0, 0.0, 10.0), speed=1.0) as (bridge, px4, outcome, _):
        px4.request_state(0)
        for k in range(250):  # 1 s: answer every 5th period only, with more than hover thrust
            s = px4.step(timeout=5.0)
            if k % 5 == 0:
                px4.controls([U_HOVER + 0.1] * 4, armed=True, time_usec=s.sensor.time_usec)
        bad = bytearray(px4.mav.hil_actuator_controls_encode(0, [1.0] * 16, 129, 1).pack(px4.mav))
        bad[-2] ^= 0x5A  # a frame hit by line noise: bad CRC, never applied
        px4._write(b"\x00line noise" + bytes(bad))
        for _ in range(100):  # 0.4 s with no controls: stale after 0.2 s -> motors stop
            last = px4.step(timeout=5.0)
    states = outcome["result"].states
    t, z, vz = states["t"], states["p_W"][:, 2], states["v_W"][:, 2]
    assert z[np.searchsorted(t, 1.0)] > 10.3  # climbed on controls that arrived between sensor periods
    assert vz[-1] < -0.5 and vz[-1] < vz[np.searchsorted(t, 1.0)] - 3.0  # stale controls: motors stopped, falling
    assert bridge.stats["bad_packets"] >= 1 and 40 <= bridge.stats["controls"] <= 50
    st = last.state[-1]  # HIL_STATE_QUATERNION over serial too: NED vz [cm/s] is minus the truth's up speed
    assert st.vz == pytest.approx(-100 * np.interp(st.time_usec * 1e-6, t, vz), abs=5)


def test_cli_hitl_on_a_pty():
    with _pty() as (master, device):
        proc = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "cufund.apps.cli",
                "px4-sim",
                "square_sensors",
                "--hitl",
                device,
                "--speed",
                "5",
                "--duration",
                "0.4",
                "--set",
                "vehicle=iris",
            ],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            px4 = Px4Harness.fd(master)
            sensors = []
            while proc.poll() is None:
                sensors += [m for m in px4.poll(0.05) if m.get_type() == "HIL_SENSOR"]
            sensors += [m for m in px4.poll(0.2) if m.get_type() == "HIL_SENSOR"]
            out, err = proc.communicate(timeout=30)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    assert proc.returncode == 0, err
    assert "HITL, lockstep off" in out and "status: completed (duration elapsed)" in out
    assert len(sensors) >= 90 and sensors[0].time_usec == 4000


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--speed=-2"], "--speed must be"),
        (["--hitl", "/nonexistent/tty"], "cannot open serial port /nonexistent/tty"),
        (["--set", "vehicle=nope"], "vehicle"),
        (["--duration", "0"], "--duration must be"),
        (["--hitl", "/dev/null", "--speed", "max"], "--speed max needs lockstep"),
        (["--cpu", "100000"], "--cpu must be one of the CPUs"),
    ],
)
def test_cli_rejects_bad_usage(argv, message, capsys):
    from cufund.apps.cli import main

    assert main(["px4-sim", "square_sensors", *argv]) == 2
    assert message in capsys.readouterr().err


@pytest.mark.parametrize("kwargs, match", [({"device": ""}, "device must be"), ({"baud": 0}, "baud must be")])
def test_serial_link_validates(kwargs, match):
    with pytest.raises(ValueError, match=match):
        SerialLink(**{"device": "/dev/null", "baud": 9600, **kwargs})


def test_hitl_relays_the_flight_controller_to_a_ground_station():
    """As Gazebo's HITL mode: the board's MAVLink goes to QGroundControl over UDP, QGroundControl's back to it."""
    from pymavlink.dialects.v20 import common as mavlink

    qgc = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    qgc.bind(("127.0.0.1", 0))
    qgc.settimeout(5.0)
    gcs_mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    try:
        with _hitl(duration=2.0, speed=1.0, gcs=GcsForward("127.0.0.1", qgc.getsockname()[1])) as (bridge, px4, _, _t):
            px4.step()
            px4.heartbeat(armed=True)  # the flight controller's heartbeat, over the serial line
            heard = []
            while not any(m.get_type() == "HEARTBEAT" for m in heard):
                data, relay = qgc.recvfrom(65536)
                heard += gcs_mav.parse_buffer(data) or []
            hb = next(m for m in heard if m.get_type() == "HEARTBEAT")
            assert hb.autopilot == 12 and hb.base_mode & 128  # PX4's, armed: relayed as it was sent
            arm = gcs_mav.command_long_encode(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)  # QGC -> the board (sys 1, comp 1)
            qgc.sendto(arm.pack(gcs_mav), relay)
            got = []
            for _ in range(200):
                s = px4.step(timeout=5.0)
                got += [m for m in s.other if m.get_type() == "COMMAND_LONG"]
                if got:
                    break
            assert got and got[0].command == 400 and got[0].get_srcSystem() == 255
            assert bridge.stats["commands"] == 0  # addressed to the board, not answered by the simulator
    finally:
        qgc.close()


def test_pacing_holds_real_time_and_drops_a_stall_instead_of_bursting(monkeypatch):
    from cufund.apps.mavlink import px4_sim

    class Clock:  # a fake wall clock: sleeping advances it
        now, slept = 100.0, []

        def perf_counter(self):
            return self.now

        def sleep(self, s):
            self.slept.append(s)
            self.now += s

    clock = Clock()
    monkeypatch.setattr(px4_sim, "time", clock)
    with _pty() as (_, device):
        cfg = ScenarioConfig.from_dict({"name": "pace", "vehicle": "iris", "sensors": IDEAL})
        bridge = Px4SimulatorBridge(cfg, SerialLink(device), Px4BridgeParams(lockstep=False, speed=2.0))
        try:
            bridge._pace(0.0)
            bridge._pace(0.004)  # 2x real time: 2 ms of wall per 4 ms period
            assert clock.slept == [pytest.approx(0.002)]
            clock.now += 1.0  # a 1 s stall
            bridge._pace(0.008)  # behind by ~1 s: no sleep, and the debt is dropped...
            bridge._pace(0.012)  # ...so the next period waits its 2 ms again instead of bursting
            assert clock.slept == [pytest.approx(0.002), pytest.approx(0.002)]
        finally:
            bridge.close()
