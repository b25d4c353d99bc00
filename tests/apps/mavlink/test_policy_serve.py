"""A learned policy behind ``cufund serve``: the shipped PPO policy (controller kind ``policy``) flies square_policy's
vehicle on its estimate (IMU, motion capture, IMU propagator) with the commander as planner, in a ``cufund serve``
process; a pymavlink ground station on 127.0.0.1 arms it, takes off to 1.5 m, sees it hold there and lands it."""

from __future__ import annotations

import math
import subprocess
import time

import pytest
from pymavlink import mavutil

pytest.importorskip("onnxruntime")

from mavlink_support import SPEED, Gcs, free_port
from process_support import cufund_serve

M = mavutil.mavlink
ALT = 1.5
TOL_M = 0.2
"""How near the target the policy holds: over MAVLink it held 1.60 m for 1.5 m and 7 cm off home (its steady
error in the env is 11.5 cm, docs/guides/learning.md); 5 cm is not reached."""


def test_pymavlink_flies_the_learned_policy_through_cufund_serve():
    port = free_port()
    serve = cufund_serve(
        "square_policy", "--set", "planner={kind: commander}", "--mavlink", f"udpout:127.0.0.1:{port}",
        "--api", "none", "--speed", str(SPEED), "--duration", "120",
    )  # fmt: skip
    g = Gcs(port)
    try:
        g.recv("HEARTBEAT", 60.0)
        g.heartbeat()
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
        # PX4's NAV_TAKEOFF param7 is AMSL: home (30 m AMSL) + alt
        ack = g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, 30.0 + ALT)
        assert ack.result == M.MAV_RESULT_ACCEPTED
        g.wait("GLOBAL_POSITION_INT", lambda m: abs(m.relative_alt / 1e3 - ALT) < TOL_M, 40)
        # arrived: at the point above home in all three axes (the climb's sideways transient has settled)
        g.wait("LOCAL_POSITION_NED", lambda m: abs(-m.z - ALT) < TOL_M / 2 and math.hypot(m.x, m.y) < TOL_M / 2, 20)
        # holding: over the next 2 s of telemetry the vehicle stays near the point above home (NED from home)
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            m = g.wait("LOCAL_POSITION_NED", lambda _m: True, 5.0)
            assert abs(-m.z - ALT) < TOL_M and math.hypot(m.x, m.y) < TOL_M, m
        assert g.command(M.MAV_CMD_NAV_LAND).result == M.MAV_RESULT_ACCEPTED
        g.wait("EXTENDED_SYS_STATE", lambda m: m.landed_state == M.MAV_LANDED_STATE_ON_GROUND, 60)
    finally:
        g.close()
        if serve.poll() is None:
            serve.terminate()
        try:
            out = serve.communicate(timeout=10)[0]
        except subprocess.TimeoutExpired:
            serve.kill()
            out = serve.communicate()[0]
    assert "Traceback" not in (out or ""), out
