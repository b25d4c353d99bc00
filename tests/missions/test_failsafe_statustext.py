"""A failsafe in a live commander flight reaches a real MAVLink client (pymavlink) as STATUSTEXT with PX4's
severity, and the commander flies it (its mode becomes RTL)."""

from __future__ import annotations

import math

from pymavlink import mavutil

from mavlink_support import OPEN_FIELD, vehicle

M = mavutil.mavlink


def test_geofence_breach_is_a_statustext_warning_and_returns():
    scenario = {**OPEN_FIELD, "failsafe": {"GF_MAX_VER_DIST": 1.0, "GF_ACTION": 3}}
    with vehicle(scenario=scenario) as (live, _ep, (g,)):
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
        # take off to 1.5 m (home is 30 m AMSL): the vertical fence at 1 m above home is crossed on the way
        ack = g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, 31.5)
        assert ack.result == M.MAV_RESULT_ACCEPTED
        text = g.wait("STATUSTEXT", lambda m: "failsafe" in m.text, 30)
        assert text.severity == M.MAV_SEVERITY_WARNING  # PX4 warns on a geofence return
        assert "GF_MAX_VER_DIST" in text.text
        ev = live.events.of_kind("failsafe")
        assert len(ev) == 1 and ev[0]["action"] == "rtl"
        g.wait("HEARTBEAT", lambda m: m.custom_mode >> 24 in (5, 6), 10)  # PX4 AUTO.RTL (5) then AUTO.LAND (6)


def test_a_live_run_without_a_commander_shows_the_supervisors_events():
    from cufund.apps.live import LiveRun
    from cufund.missions.failsafe_supervisor import FailsafeSupervisor

    live = LiveRun("square", start=False)
    try:
        sup = next(c for c in live.simulator.components if isinstance(c, FailsafeSupervisor))
        assert live.commander is None and live.events is sup.events  # the ground station and MAVLink follow these
    finally:
        live.stop()
