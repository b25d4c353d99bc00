"""A learned policy behind cufund's MAVLink endpoint (what ``cufund serve`` runs): the shipped PPO policy (controller
kind ``policy``) flies square_policy's vehicle on its estimate (IMU, motion capture, IMU propagator) with the
commander as planner; a pymavlink ground station arms it, takes off to 1.5 m, sees it hold there and lands it."""

from __future__ import annotations

import math
import time

import pytest
from pymavlink import mavutil

pytest.importorskip("onnxruntime")

from cufund.scenarios import load_scenario
from mavlink_support import vehicle

M = mavutil.mavlink
ALT = 1.5
TOL_M = 0.2
"""How near the target the policy holds: over pymavlink it held 1.60 m for 1.5 m and 7 cm off home (its steady
error in the env is 11.5 cm, docs/guides/learning.md); 5 cm is not reached."""


def _scenario():
    return load_scenario("square_policy", ["planner={kind: commander}", "duration=600.0"])


def test_pymavlink_flies_the_learned_policy_through_the_endpoint():
    with vehicle(scenario=_scenario()) as (live, _ep, (g,)):
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
        # PX4's NAV_TAKEOFF param7 is AMSL: home (30 m AMSL) + alt
        ack = g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, 30.0 + ALT)
        assert ack.result == M.MAV_RESULT_ACCEPTED
        g.wait("GLOBAL_POSITION_INT", lambda m: abs(m.relative_alt / 1e3 - ALT) < TOL_M, 40)
        # holding: over the next 2 s of telemetry the altitude stays near the target and the vehicle stays over home
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            m = g.recv("GLOBAL_POSITION_INT", 5.0)
            assert abs(m.relative_alt / 1e3 - ALT) < TOL_M, m
        tel = live.telemetry()
        assert math.dist(tel["p_W"][:2], tel["home_p_W"][:2]) < TOL_M
        assert g.command(M.MAV_CMD_NAV_LAND).result == M.MAV_RESULT_ACCEPTED
        g.wait("EXTENDED_SYS_STATE", lambda m: m.landed_state == M.MAV_LANDED_STATE_ON_GROUND, 60)
