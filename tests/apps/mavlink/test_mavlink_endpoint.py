"""cufund's vehicle endpoint driven by a pymavlink ground station: telemetry in PX4's frames and units, commands
with their acks, the mission and parameter protocols, offboard setpoints. Positions are checked against the
live run's own telemetry converted here by hand (NED = (north, east, down) = (y, x, -z) of ENU) and against
cufund.sensors.geodesy, not against the endpoint's frames module."""

from __future__ import annotations

import math
import socket
import time

import numpy as np
import pytest
from pymavlink import mavutil

from cufund.apps.mavlink.link import LinkAddress, UdpLink
from cufund.apps.mavlink.vehicle_endpoint import VehicleEndpoint
from cufund.sensors.geodesy import GeoPoint, enu_to_lla, lla_to_enu
from mavlink_support import Gcs, free_port, vehicle

M = mavutil.mavlink
HOME = GeoPoint(22.4196, 114.2068, 30.0)  # the GPS model's default home = the endpoint's default origin


def _px4_mode(hb) -> str:
    return mavutil.interpret_px4_mode(hb.base_mode, hb.custom_mode)


def _take_off(g: Gcs, alt: float = 1.5) -> None:
    assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
    # PX4's NAV_TAKEOFF param7 is AMSL: home (30 m AMSL) + alt
    assert (
        g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, 30.0 + alt).result
        == M.MAV_RESULT_ACCEPTED
    )
    g.wait("GLOBAL_POSITION_INT", lambda m: abs(m.relative_alt / 1e3 - alt) < 0.05, 20)
    g.wait("HEARTBEAT", lambda m: _px4_mode(m) == "LOITER", 10)


def test_telemetry_is_px4_frames_and_units():
    with vehicle() as (live, _ep, (g,)):
        hb = g.recv("HEARTBEAT")
        assert (hb.type, hb.autopilot) == (M.MAV_TYPE_QUADROTOR, M.MAV_AUTOPILOT_PX4)
        assert _px4_mode(hb) == "LOITER" and not hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
        assert g.recv("EXTENDED_SYS_STATE").landed_state == M.MAV_LANDED_STATE_ON_GROUND
        _take_off(g, 1.5)
        live.pause()  # a still vehicle: the endpoint's messages and the run's telemetry describe the same state
        time.sleep(0.3)  # the step in progress ends and what was sent before arrives
        g.drain()
        tel = live.telemetry()
        p, v, q = np.array(tel["p_W"]), np.array(tel["v_W"]), np.array(tel["q_WB"])
        lp = g.recv("LOCAL_POSITION_NED")
        np.testing.assert_allclose([lp.x, lp.y, lp.z], [p[1], p[0], -p[2]], atol=1e-5)
        np.testing.assert_allclose([lp.vx, lp.vy, lp.vz], [v[1], v[0], -v[2]], atol=1e-5)
        gp = g.recv("GLOBAL_POSITION_INT")
        back = lla_to_enu(np.array([gp.lat * 1e-7, gp.lon * 1e-7, gp.alt * 1e-3]), HOME)
        np.testing.assert_allclose(back, p, atol=0.02)  # degE7 ~ 1 cm, mm altitude
        home = np.array(tel["home_p_W"])
        assert gp.relative_alt * 1e-3 == pytest.approx(p[2] - home[2], abs=2e-3)
        hp = g.recv("HOME_POSITION")
        np.testing.assert_allclose([hp.x, hp.y, hp.z], [home[1], home[0], -home[2]], atol=1e-5)
        lla = enu_to_lla(home, HOME)
        assert (hp.latitude, hp.longitude) == (round(lla[0] * 1e7), round(lla[1] * 1e7))
        yaw_enu = math.atan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] ** 2 + q[3] ** 2))
        att = g.recv("ATTITUDE")
        assert math.remainder(att.yaw - (math.pi / 2 - yaw_enu), 2 * math.pi) == pytest.approx(0, abs=1e-5)
        assert gp.hdg == round(math.degrees(math.pi / 2 - yaw_enu) * 100) % 36000
        aq = g.recv("ATTITUDE_QUATERNION")  # its yaw agrees with ATTITUDE's (PX4's FRD -> NED quaternion)
        yaw_q = math.atan2(2 * (aq.q1 * aq.q4 + aq.q2 * aq.q3), 1 - 2 * (aq.q3**2 + aq.q4**2))
        assert yaw_q == pytest.approx(att.yaw, abs=1e-5)
        assert g.recv("EXTENDED_SYS_STATE").landed_state == M.MAV_LANDED_STATE_IN_AIR
        assert g.recv("ALTITUDE").altitude_relative == pytest.approx(p[2] - home[2], abs=1e-4)
        assert g.recv("HEARTBEAT").base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
        live.resume()


def test_commands_reposition_land_and_refusals():
    with vehicle() as (live, _ep, (g,)):
        assert (
            g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, 32).result == M.MAV_RESULT_DENIED
        )  # disarmed
        assert (
            g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 1).result == M.MAV_RESULT_DENIED
        )  # MANUAL: no sticks
        assert g.command(31999).result == M.MAV_RESULT_UNSUPPORTED
        _take_off(g, 1.5)
        home = np.array(live.telemetry()["home_p_W"])
        target = home + np.array([1.0, 0.5, 0.5])  # 1 m east, 0.5 m north, 0.5 m up
        lat, lon, alt = enu_to_lla(target, HOME)
        g.mav.command_int_send(
            1,
            1,
            M.MAV_FRAME_GLOBAL_INT,
            M.MAV_CMD_DO_REPOSITION,
            0,
            0,
            -1,
            0,
            0,
            math.nan,
            round(lat * 1e7),
            round(lon * 1e7),
            float(alt),
        )
        assert (
            g.recv("COMMAND_ACK", cond=lambda m: m.command == M.MAV_CMD_DO_REPOSITION).result == M.MAV_RESULT_ACCEPTED
        )
        g.wait(
            "LOCAL_POSITION_NED",
            lambda m: np.hypot(m.y - target[0], m.x - target[1]) < 0.1 and abs(-m.z - target[2]) < 0.1,
            20,
        )
        unset = 2**31 - 1  # COMMAND_INT's "no value": keep lat/lon, change the height above home only
        g.mav.command_int_send(
            1,
            1,
            M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            M.MAV_CMD_DO_REPOSITION,
            0,
            0,
            -1,
            0,
            0,
            math.nan,
            unset,
            unset,
            1.0,
        )
        assert (
            g.recv("COMMAND_ACK", cond=lambda m: m.command == M.MAV_CMD_DO_REPOSITION).result == M.MAV_RESULT_ACCEPTED
        )
        g.wait(
            "LOCAL_POSITION_NED",
            lambda m: abs(-m.z - (home[2] + 1.0)) < 0.05 and np.hypot(m.y - target[0], m.x - target[1]) < 0.1,
            20,
        )
        g.mav.command_int_send(
            1,
            1,
            M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            M.MAV_CMD_DO_REPOSITION,
            0,
            0,
            -1,
            0,
            0,
            math.nan,
            unset,
            unset,
            -1.0,
        )  # into the ground
        assert g.recv("COMMAND_ACK", cond=lambda m: m.command == M.MAV_CMD_DO_REPOSITION).result == M.MAV_RESULT_DENIED
        assert g.command(M.MAV_CMD_NAV_LAND).result == M.MAV_RESULT_ACCEPTED
        assert _px4_mode(g.wait("HEARTBEAT", lambda m: True, 5)) == "LAND"
        g.wait("EXTENDED_SYS_STATE", lambda m: m.landed_state == M.MAV_LANDED_STATE_ON_GROUND, 30)
        g.wait("HEARTBEAT", lambda m: not m.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED, 10)  # disarmed on touchdown


def _upload(g: Gcs, items: list[tuple[int, int, int, float]], mission_type: int = 0) -> int:
    """MISSION_COUNT, answer every MISSION_REQUEST_INT; the MISSION_ACK's type."""
    g.mav.mission_count_send(1, 1, len(items), mission_type)
    while True:
        m = g.recv(["MISSION_REQUEST_INT", "MISSION_ACK"])
        if m.get_type() == "MISSION_ACK":
            return m.type
        frame, x, y, z = items[m.seq]
        g.mav.mission_item_int_send(
            1, 1, m.seq, frame, M.MAV_CMD_NAV_WAYPOINT, 0, 1, 0, 0, 0, math.nan, x, y, z, mission_type
        )


def test_mission_upload_download_clear_and_fly():
    with vehicle() as (live, _ep, (g,)):
        home = np.array(live.telemetry()["p_W"])
        wps = [home + d for d in ([1.0, 0, 1.5], [1.0, 1.0, 1.5], [0, 1.0, 2.0])]
        items = []
        for w in wps:
            lat, lon, _ = enu_to_lla(w, HOME)
            items.append(
                (M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, round(lat * 1e7), round(lon * 1e7), float(w[2] - home[2]))
            )
        assert _upload(g, items[:1] + [(99, 0, 0, 0.0)]) == M.MAV_MISSION_UNSUPPORTED_FRAME
        assert _upload(g, items[:1], mission_type=M.MAV_MISSION_TYPE_FENCE) == M.MAV_MISSION_UNSUPPORTED
        assert _upload(g, [items[0][:3] + (-0.5,)]) == M.MAV_MISSION_INVALID_PARAM7  # below home
        assert _upload(g, items) == M.MAV_MISSION_ACCEPTED
        assert live.telemetry()["mission"]["count"] == 3
        np.testing.assert_allclose(live.telemetry()["mission"]["items"], wps, atol=0.02)
        g.mav.mission_request_list_send(1, 1, 0)
        assert g.recv("MISSION_COUNT").count == 3
        for seq, (frame, x, y, z) in enumerate(items):  # downloaded exactly as uploaded
            g.mav.mission_request_int_send(1, 1, seq, 0)
            it = g.recv("MISSION_ITEM_INT", cond=lambda m, s=seq: m.seq == s)
            assert (it.frame, it.command, it.x, it.y, it.z) == (frame, M.MAV_CMD_NAV_WAYPOINT, x, y, z)
        g.mav.mission_ack_send(1, 1, 0, 0)
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
        # start as MAVSDK does: DO_SET_MODE AUTO/MISSION
        assert (
            g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4, 4).result == M.MAV_RESULT_ACCEPTED
        )
        reached = []
        while len(reached) < 3:
            reached.append(g.wait("MISSION_ITEM_REACHED", lambda m: True, 30).seq)
            tel = live.telemetry()
            assert np.linalg.norm(np.array(tel["truth_p_W"]) - wps[reached[-1]]) < 0.25
        assert reached == [0, 1, 2]
        cur = g.wait("MISSION_CURRENT", lambda m: m.mission_state == M.MISSION_STATE_COMPLETE, 5)
        assert (cur.seq, cur.total) == (3, 3)
        g.mav.mission_clear_all_send(1, 1, 0)
        assert g.recv("MISSION_ACK").type == M.MAV_MISSION_ACCEPTED
        g.mav.mission_request_list_send(1, 1, 0)
        assert g.recv("MISSION_COUNT").count == 0
        assert live.telemetry()["mission"]["count"] == 0


def test_mission_upload_rerequests_lost_items():
    with vehicle() as (live, ep, (g,)):
        ep.missions.retry_s = 0.2
        g.mav.mission_count_send(1, 1, 2, 0)
        assert g.recv("MISSION_REQUEST_INT").seq == 0  # ignored: the item "is lost"
        assert g.recv("MISSION_REQUEST_INT", 3).seq == 0  # asked again
        p = enu_to_lla(np.array([-2.0, 0.0, 1.0]), HOME)
        for seq in (1, 0):  # out of order first: the vehicle asks for the one it needs
            g.mav.mission_item_int_send(
                1,
                1,
                seq,
                M.MAV_FRAME_GLOBAL_INT,
                M.MAV_CMD_NAV_WAYPOINT,
                0,
                1,
                0,
                0,
                0,
                math.nan,
                round(p[0] * 1e7),
                round(p[1] * 1e7),
                float(p[2]),
                0,
            )
        assert g.recv("MISSION_REQUEST_INT", cond=lambda m: m.seq == 1).seq == 1
        g.mav.mission_item_int_send(
            1,
            1,
            1,
            M.MAV_FRAME_GLOBAL_INT,
            M.MAV_CMD_NAV_WAYPOINT,
            0,
            1,
            0,
            0,
            0,
            math.nan,
            round(p[0] * 1e7),
            round(p[1] * 1e7),
            float(p[2]),
            0,
        )
        assert g.recv("MISSION_ACK").type == M.MAV_MISSION_ACCEPTED
        np.testing.assert_allclose(live.telemetry()["mission"]["items"][0], [-2.0, 0.0, 1.0], atol=0.02)
        g.mav.mission_request_send(1, 1, 1, 0)  # the legacy float download: degrees, not degE7
        it = g.recv("MISSION_ITEM", cond=lambda m: m.seq == 1)
        assert (it.frame, it.x, it.y, it.z) == (
            M.MAV_FRAME_GLOBAL,
            pytest.approx(p[0], abs=2e-5),  # float32
            pytest.approx(p[1], abs=2e-5),
            pytest.approx(p[2], abs=1e-3),
        )


def test_mission_set_current_starts_from_that_item():
    with vehicle() as (live, _ep, (g,)):
        home = np.array(live.telemetry()["p_W"])
        wps = [home + d for d in ([1.0, 0, 1.5], [1.0, 1.0, 1.5], [0, 1.0, 2.0])]
        items = [
            (M.MAV_FRAME_GLOBAL_INT, *(round(c * 1e7) for c in enu_to_lla(w, HOME)[:2]), float(enu_to_lla(w, HOME)[2]))
            for w in wps
        ]
        assert _upload(g, items) == M.MAV_MISSION_ACCEPTED
        assert g.command(M.MAV_CMD_DO_SET_MISSION_CURRENT, 2).result == M.MAV_RESULT_ACCEPTED
        assert g.wait("MISSION_CURRENT", lambda m: True, 5).seq == 2
        mission = live.telemetry()["mission"]
        assert mission["count"] == 1  # the commander flies from item 2 on
        np.testing.assert_allclose(mission["items"][0], wps[2], atol=0.02)
        g.mav.mission_request_list_send(1, 1, 0)
        assert g.recv("MISSION_COUNT").count == 3  # the plan itself is unchanged
        assert g.command(M.MAV_CMD_DO_SET_MISSION_CURRENT, 7).result == M.MAV_RESULT_DENIED


def test_parameters_are_the_live_gains():
    with vehicle() as (live, _ep, (g,)):
        g.mav.param_request_list_send(1, 1)
        first = g.recv("PARAM_VALUE")
        values = {first.param_id: first.param_value}
        while len(values) < first.param_count:
            m = g.recv("PARAM_VALUE", 3)
            values[m.param_id] = m.param_value
        assert {"MPC_XY_P", "MC_ROLLRATE_P", "MPC_TILTMAX_AIR", "MIS_TAKEOFF_ALT", "COM_DL_LOSS_T"} <= set(values)
        assert values["MPC_XY_P"] == pytest.approx(3.0)  # the vehicle scenario's position.xy_p
        assert values["MPC_TILTMAX_AIR"] == pytest.approx(45.0)  # degrees on the wire
        g.mav.param_set_send(1, 1, b"MC_ROLLRATE_P", 31.5, M.MAV_PARAM_TYPE_REAL32)
        echo = g.recv("PARAM_VALUE", cond=lambda m: m.param_id == "MC_ROLLRATE_P")
        assert echo.param_value == pytest.approx(31.5)
        rate = next(c for c in live.simulator.components if type(c).__name__ == "RateController")
        assert rate.gains.roll_p == pytest.approx(31.5)  # applied to the controller flying the vehicle
        g.mav.param_set_send(1, 1, b"MPC_XY_P", -1.0, M.MAV_PARAM_TYPE_REAL32)  # refused: the old value comes back
        assert g.recv("PARAM_VALUE", cond=lambda m: m.param_id == "MPC_XY_P").param_value == pytest.approx(3.0)
        g.mav.param_request_read_send(1, 1, b"", values and list(values).index("MIS_TAKEOFF_ALT"))
        assert g.recv("PARAM_VALUE", cond=lambda m: m.param_id == "MIS_TAKEOFF_ALT").param_value == 1.5
        g.mav.param_set_send(1, 1, b"NO_SUCH_PARAM", 1.0, M.MAV_PARAM_TYPE_REAL32)
        assert "NO_SUCH_PARAM" in g.recv("STATUSTEXT", cond=lambda m: "NO_SUCH" in m.text).text


def test_message_intervals_and_requests():
    with vehicle() as (_live, _ep, (g,)):
        ack = g.command(M.MAV_CMD_REQUEST_MESSAGE, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        assert ack.result == M.MAV_RESULT_ACCEPTED
        caps = g.recv("AUTOPILOT_VERSION").capabilities
        for bit in (
            M.MAV_PROTOCOL_CAPABILITY_MISSION_INT,
            M.MAV_PROTOCOL_CAPABILITY_COMMAND_INT,
            M.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT,
            M.MAV_PROTOCOL_CAPABILITY_MAVLINK2,
        ):
            assert caps & bit
        assert (
            g.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, -1).result
            == M.MAV_RESULT_ACCEPTED
        )
        g.drain()
        with pytest.raises(AssertionError):
            g.recv("GLOBAL_POSITION_INT", 1.0)  # disabled
        assert (
            g.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 0).result
            == M.MAV_RESULT_ACCEPTED
        )
        g.recv("GLOBAL_POSITION_INT", 2.0)  # back at its default rate
        assert g.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 60000, 1e5).result == M.MAV_RESULT_UNSUPPORTED


def test_offboard_position_setpoints():
    with vehicle() as (live, _ep, (g,)):
        _take_off(g, 1.5)
        assert (
            g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6).result == M.MAV_RESULT_DENIED
        )  # no setpoint stream yet, as PX4
        p = np.array(live.telemetry()["p_W"]) + np.array([0.0, 0.8, 0.3])  # 0.8 m north, 0.3 m up
        mask = 0x9F8  # position and yaw used (velocity, acceleration, yaw rate ignored)
        yaw_ned = 0.0  # nose north = ENU yaw pi/2

        def send() -> None:
            g.mav.set_position_target_local_ned_send(
                0, 1, 1, M.MAV_FRAME_LOCAL_NED, mask, p[1], p[0], -p[2], 0, 0, 0, 0, 0, 0, yaw_ned, 0
            )

        for _ in range(5):
            send()
        assert g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6).result == M.MAV_RESULT_ACCEPTED

        def offboard(m) -> bool:
            send()  # a stream, as offboard needs (every telemetry message here: ~50 Hz)
            return m.get_type() == "HEARTBEAT" and _px4_mode(m) == "OFFBOARD"

        g.wait(["HEARTBEAT", "LOCAL_POSITION_NED"], offboard, 5)

        def there(m) -> bool:
            send()  # a stream, as offboard needs
            return (
                np.hypot(m.x - p[1], m.y - p[0]) < 0.1
                and abs(-m.z - p[2]) < 0.1
                and abs(math.remainder(live.telemetry()["rpy"][2] - math.pi / 2, 2 * math.pi)) < 0.05
            )

        g.wait("LOCAL_POSITION_NED", there, 20)
        # the stream stops: the commander holds (COM_OF_LOSS_T), PX4's offboard loss failsafe
        g.wait("HEARTBEAT", lambda m: _px4_mode(m) == "LOITER", 10)


def test_offboard_attitude_target_turns_the_vehicle():
    with vehicle() as (live, _ep, (g,)):
        _take_off(g, 1.5)
        vp = live.built.context.vehicle
        hover = vp.mass * 9.81 / (4 * vp.k_f * vp.rotor_speed_max**2)  # normalised thrust that carries the weight

        def send() -> None:  # level, nose north (PX4 q_NED_FRD = identity), hover thrust
            g.mav.set_attitude_target_send(0, 1, 1, 0b0000_0111, [1.0, 0.0, 0.0, 0.0], 0, 0, 0, hover)

        for _ in range(5):
            send()
        assert g.command(M.MAV_CMD_DO_SET_MODE, M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 6).result == M.MAV_RESULT_ACCEPTED

        def turned(m) -> bool:
            send()
            return (
                m.get_type() == "ATTITUDE"
                and abs(m.yaw) < math.radians(2)
                and abs(m.roll) < math.radians(2)
                and abs(m.pitch) < math.radians(2)
            )

        g.wait(["ATTITUDE", "LOCAL_POSITION_NED"], turned, 15)
        tel = live.telemetry()
        assert tel["mode"] == "offboard" and tel["flight_mode"] == "attitude"
        assert tel["rpy"][2] == pytest.approx(math.pi / 2, abs=math.radians(2))  # north is ENU yaw +90 degrees
        assert abs(tel["v_W"][2]) < 0.3  # hover thrust, converted to newtons, about carries the vehicle


def test_udpin_link_answers_whoever_writes():
    port = free_port()
    with vehicle(links=0, extra_links=[f"udpin:127.0.0.1:{port}"]) as (_live, ep, _):
        client = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, dialect="common")
        try:
            client.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            hb = client.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
            assert hb is not None and hb.autopilot == M.MAV_AUTOPILOT_PX4
            assert ep.links[0].local_address == ("127.0.0.1", port)
        finally:
            client.close()


def test_link_urls_and_binding():
    assert LinkAddress.parse("udpout:127.0.0.1:14550") == LinkAddress("udpout", "127.0.0.1", 14550)
    assert LinkAddress.parse("udpin:14551") == LinkAddress("udpin", "127.0.0.1", 14551)  # loopback by default
    for bad in ("tcp:1.2.3.4:5", "udpout:127.0.0.1", "udpout:127.0.0.1:x", "udpout:127.0.0.1:0", "udpin:1:2:3"):
        with pytest.raises(ValueError, match="link"):
            LinkAddress.parse(bad, "link")
    with pytest.raises(ValueError, match="system_id"):
        VehicleEndpoint(object(), ["udpout:127.0.0.1:14550"], system_id=0)
    with pytest.raises(ValueError, match="component_id"):
        VehicleEndpoint(object(), ["udpout:127.0.0.1:14550"], component_id=300)
    for rates, match in (
        ({"HEARTBEAT": 0.0}, "HEARTBEAT"),
        ({"ATTITUDE": float("nan")}, "ATTITUDE"),
        ({"NO_SUCH_STREAM": 1.0}, "NO_SUCH_STREAM"),
    ):
        with pytest.raises(ValueError, match=match):
            VehicleEndpoint(object(), ["udpout:127.0.0.1:14550"], rates_hz=rates)
    ep = VehicleEndpoint(object(), ["udpout:127.0.0.1:14550"], max_thrust_N=10.0, rates_hz={"ATTITUDE": 50.0})
    try:  # one rate changed, every other stream (the heartbeat first) kept at its default
        assert ep.intervals["ATTITUDE"] == pytest.approx(0.02) and ep.intervals["HEARTBEAT"] == pytest.approx(1.0)
    finally:
        ep.close()
    with vehicle() as (_live, ep, (_g,)):
        assert ep.links[0].local_address[0] == "127.0.0.1"
    probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        probe.connect(("192.0.2.77", 14550))  # TEST-NET-1: what the kernel would send from (no packet leaves)
        route = probe.getsockname()[0]
    except OSError:
        route = None  # no route off this host: nothing to compare
    finally:
        probe.close()
    if route is not None:
        link = UdpLink("udpout:192.0.2.77:14550")
        try:  # a udpout to another host listens on its route's interface, not on every interface
            assert link.local_address[0] == route != "0.0.0.0"
        finally:
            link.close()
