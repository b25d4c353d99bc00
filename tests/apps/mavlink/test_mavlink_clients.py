"""Real MAVLink clients fly cufund's vehicle: MAVSDK (mavsdk_server from mavsdk-grpc, driven through its gRPC
wrapper) and MAVProxy, each a subprocess with timeouts, killed in teardown."""

from __future__ import annotations

import asyncio
import math
import re
import socket
import subprocess
from pathlib import Path

import numpy as np
import pytest

from cufund.sensors.geodesy import GeoPoint, enu_to_lla
from mavlink_support import SPEED, free_port, vehicle
from process_support import ProcessOutput, cufund_serve, interrupt, kill, mavproxy

mavsdk = pytest.importorskip("mavsdk_grpc")
from mavsdk_grpc.mission import MissionItem, MissionPlan  # noqa: E402  (after the importorskip)
from mavsdk_grpc.offboard import PositionNedYaw  # noqa: E402

HOME = GeoPoint(22.4196, 114.2068, 30.0)


def _item(lat: float, lon: float, rel_alt: float) -> MissionItem:
    nan = math.nan
    return MissionItem(
        lat,
        lon,
        rel_alt,
        1.0,
        False,
        nan,
        nan,
        MissionItem.CameraAction.NONE,
        nan,
        nan,
        0.2,
        nan,
        nan,
        MissionItem.VehicleAction.NONE,
    )


async def _first(stream, cond, timeout: float):
    async def scan():
        async for x in stream:
            if cond(x):
                return x
        return None

    return await asyncio.wait_for(scan(), timeout)


def test_mavsdk_connects_takes_off_flies_a_mission_offboard_and_lands():
    api, grpc = free_port(), free_port(socket.SOCK_STREAM)
    server = subprocess.Popen(
        [str(Path(mavsdk.__file__).parent / "bin" / "mavsdk_server"), "-p", str(grpc), f"udpin://127.0.0.1:{api}"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    path: list[np.ndarray] = []
    try:
        with vehicle(links=0, extra_links=[f"udpout:127.0.0.1:{api}"]) as (live, _ep, _):
            remove = live.add_listener(lambda tel: path.append(np.array(tel["truth_p_W"])), 50.0)

            async def fly() -> tuple:
                drone = mavsdk.System(mavsdk_server_address="127.0.0.1", port=grpc)
                await drone.connect()
                await _first(drone.core.connection_state(), lambda s: s.is_connected, 15)
                await _first(
                    drone.telemetry.health(),
                    lambda h: h.is_global_position_ok and h.is_home_position_ok and h.is_armable,
                    10,
                )
                assert (await _first(drone.telemetry.flight_mode(), lambda m: True, 5)).name == "HOLD"
                await drone.action.arm()
                await _first(drone.telemetry.armed(), bool, 5)
                await drone.action.set_takeoff_altitude(2.0)  # PARAM_SET MIS_TAKEOFF_ALT
                assert await drone.action.get_takeoff_altitude() == pytest.approx(2.0)
                await drone.action.takeoff()
                up = await _first(drone.telemetry.position(), lambda p: p.relative_altitude_m > 1.9, 20)
                home = await _first(drone.telemetry.home(), lambda h: True, 5)
                home_W = np.array(live.telemetry()["home_p_W"])
                wps = [home_W + d for d in ([1.5, 0, 2.0], [1.5, 1.5, 2.0], [0, 1.5, 2.5])]
                items = [_item(*enu_to_lla(w, HOME)[:2], float(w[2] - home_W[2])) for w in wps]
                await drone.mission.upload_mission(MissionPlan(items))
                await drone.mission.start_mission()
                done = await _first(drone.mission.mission_progress(), lambda p: p.current == p.total, 40)
                assert await drone.mission.is_mission_finished()
                # offboard: MAVSDK streams the setpoint itself, then switches to OFFBOARD (PX4's order)
                ned = await _first(drone.telemetry.position_velocity_ned(), lambda p: True, 5)
                target = (ned.position.north_m - 1.0, ned.position.east_m, ned.position.down_m + 0.5, 180.0)
                await drone.offboard.set_position_ned(PositionNedYaw(*target))
                await drone.offboard.start()
                assert await _first(drone.telemetry.flight_mode(), lambda m: m.name == "OFFBOARD", 5)
                at = await _first(
                    drone.telemetry.position_velocity_ned(),
                    lambda p: abs(p.position.north_m - target[0]) < 0.1 and abs(p.position.down_m - target[2]) < 0.1,
                    20,
                )
                heading = await _first(drone.telemetry.heading(), lambda h: abs(h.heading_deg - 180) < 3, 10)
                await drone.offboard.stop()  # PX4 holds
                await _first(drone.telemetry.flight_mode(), lambda m: m.name == "HOLD", 5)
                await drone.action.land()
                await _first(drone.telemetry.in_air(), lambda a: not a, 30)
                await _first(drone.telemetry.armed(), lambda a: not a, 10)
                return up, home, wps, done, at, heading

            up, home, wps, done, at, heading = asyncio.run(asyncio.wait_for(fly(), 90))
            remove()
            assert (done.current, done.total) == (3, 3)
            assert up.absolute_altitude_m - home.absolute_altitude_m == pytest.approx(up.relative_altitude_m, abs=0.01)
            lla = enu_to_lla(np.array(live.telemetry()["home_p_W"]), HOME)
            assert (home.latitude_deg, home.longitude_deg) == pytest.approx(tuple(lla[:2]), abs=2e-7)
            assert at.position.east_m == pytest.approx(wps[2][0], abs=0.2)  # local NED east = world ENU x
            assert heading.heading_deg == pytest.approx(180.0, abs=3)
            track = np.array(path)
            for w in wps:  # the flown path passed each waypoint
                assert np.min(np.linalg.norm(track - w, axis=1)) < 0.25
            assert live.telemetry()["landed"] and not live.telemetry()["armed"]
    finally:
        log = kill(server)
    assert "System discovered" in log


def test_mavproxy_drives_cufund_serve(tmp_path):
    port = free_port()
    serve = cufund_serve(
        "vehicle", "--mavlink", f"udpout:127.0.0.1:{port}", "--api", "none", "--speed", str(SPEED), "--duration", "60"
    )
    proxy = mavproxy(port, tmp_path)
    try:
        out = ProcessOutput(proxy)

        def do(cmd: str) -> None:
            proxy.stdin.write(cmd + "\n")  # type: ignore[union-attr]
            proxy.stdin.flush()  # type: ignore[union-attr]

        out.expect(r"Detected vehicle 1:1", 30)
        out.expect(r"Mode LOITER|LOITER> ", 10)  # PX4's Hold, decoded by MAVProxy from the custom mode
        do("arm throttle")
        out.expect(r"COMPONENT_ARM_DISARM: ACCEPTED", 10)
        do("takeoff 2")  # MAVProxy sends the height as param7; at or below home's AMSL it is a height
        out.expect(r"NAV_TAKEOFF: ACCEPTED", 10)
        out.expect(r"Mode TAKEOFF|TAKEOFF> ", 10)
        out.expect(r"AP: mode hold: takeoff done", 20)
        # MAVProxy 1.8.75's `mode NAME` passes PX4's mode tuple to COMMAND_LONG and fails before sending; its
        # `long` command sends the same DO_SET_MODE (custom mode enabled, AUTO, sub-mode) as QGroundControl
        do("long DO_SET_MODE 1 4 5")  # AUTO.RTL
        out.expect(r"DO_SET_MODE: ACCEPTED", 10)
        out.expect(r"AP: mode rtl", 10)
        out.expect(r"Mode LAND|LAND> ", 40)  # RTL ends with a landing, shown as PX4's AUTO.LAND
        out.expect(r"AP: landed", 40)
        out.expect(r"DISARMED", 10)
        do("long DO_SET_MODE 1 1 0")  # MANUAL: no sticks here, refused
        out.expect(r"DO_SET_MODE: DENIED", 10)
    finally:
        kill(proxy, pumped=True)
        log = interrupt(serve)
    assert re.search(r"MAVLink vehicle 1: udpout:127.0.0.1:\d+ \(local 127.0.0.1:\d+\)", log)
