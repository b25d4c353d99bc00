"""A fleet on MAVLink: one system per vehicle on PX4 SITL's multi-instance ports, checked against PX4's own port
numbers and against real clients (MAVSDK's mavsdk_server, one per vehicle as for N px4_sitl instances; MAVProxy
on the shared ground-station port), each a subprocess with timeouts, killed in teardown."""

from __future__ import annotations

import asyncio
import contextlib
import re
import socket
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from cufund.apps.mavlink.fleet_endpoints import FleetEndpoints
from cufund.apps.mavlink.fleet_ports import FleetPorts
from mavlink_support import OPEN_FIELD, SPEED, Gcs, free_port
from process_support import BIN, ProcessOutput, cufund_serve, interrupt, kill, mavproxy

# PX4 v1.14 ROMFS/px4fmu_common/init.d-posix/px4-rc.mavlink and rcS, for instance i (px4_sitl -i i):
#   udp_gcs_port_local=$((18570+px4_instance))       (remote: QGroundControl's 14550)
#   udp_offboard_port_local=$((14580+px4_instance))
#   udp_offboard_port_remote=$((14540+px4_instance))
#   MAV_SYS_ID=$((px4_instance+1));  simulator TCP port 4560+px4_instance
PX4_RC = {"gcs_local": 18570, "gcs_remote": 14550, "api_local": 14580, "api_remote": 14540, "sim_tcp": 4560}


def test_the_port_rule_is_px4_sitl_instances():
    from cufund.apps.mavlink.fleet_ports import px4_sim_port

    plan = FleetPorts().all(3)
    for i, v in enumerate(plan):
        assert v.system_id == i + 1
        assert v.links == (
            (f"udpout:127.0.0.1:{PX4_RC['gcs_remote']}", PX4_RC["gcs_local"] + i),
            (f"udpout:127.0.0.1:{PX4_RC['api_remote'] + i}", PX4_RC["api_local"] + i),
        )
        assert px4_sim_port(i) == PX4_RC["sim_tcp"] + i


def test_listening_links_take_one_port_each_and_overlaps_are_refused():
    plan = FleetPorts(gcs="udpin:127.0.0.1:15000", api=None).all(3)
    assert [v.links for v in plan] == [((f"udpin:127.0.0.1:{15000 + i}", 0),) for i in range(3)]
    with pytest.raises(ValueError, match="overlap"):
        FleetPorts(gcs="udpin:127.0.0.1:15000", api="udpin:127.0.0.1:15001").all(2)
    with pytest.raises(ValueError, match="1 to 255 vehicles here"):
        FleetPorts().all(256)
    assert FleetPorts(first_system_id=11).vehicle(2, 3).system_id == 13
    with pytest.raises(ValueError, match="1 to 6 vehicles here"):
        FleetPorts(first_system_id=250).all(7)
    with pytest.raises(ValueError, match="first_system_id"):
        FleetPorts(first_system_id=0)
    with pytest.raises(ValueError, match="at least one"):
        FleetPorts(gcs=None, api=None)
    with pytest.raises(ValueError, match="gcs must be"):
        FleetPorts(gcs="tcp:1.2.3.4:5")


def test_a_vehicle_never_sends_to_another_vehicles_own_port():
    """PX4's rule runs out at 40 vehicles: vehicle 41's offboard link would send to 14540 + 40 = 14580, vehicle 1's
    local port (its client would be vehicle 41). Such a fleet is refused naming the way out."""
    assert len(FleetPorts().all(40)) == 40
    with pytest.raises(ValueError, match="14580.*--local-ports any"):
        FleetPorts().all(41)
    assert len(FleetPorts(px4_local_ports=False).all(100)) == 100  # the kernel's ports: no clash
    with pytest.raises(ValueError, match="15000"):  # a link sending to another's listening port
        FleetPorts(gcs="udpin:127.0.0.1:15000", api="udpout:127.0.0.1:14999").all(2)


def _port_block(n: int) -> int:
    """A base port with base .. base + n - 1 free for UDP on 127.0.0.1."""
    for _ in range(200):
        base = free_port()
        socks = []
        try:
            for p in range(base, base + n):
                s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                socks.append(s)
                s.bind(("127.0.0.1", p))
            return base
        except OSError:
            continue
        finally:
            for s in socks:
                s.close()
    raise AssertionError(f"no {n} consecutive free UDP ports")


def fleet_config(n: int) -> dict[str, Any]:
    """A fleet of ``n`` commander vehicles 3 m apart on the open field (uav1 at x = 0, uav2 at x = 3, ...)."""
    vehicles = [{"name": f"uav{i + 1}", "start": {"p": [3.0 * i, 0.0, 0.0]}} for i in range(n)]
    return {**OPEN_FIELD, "name": "open_field_fleet", "vehicles": vehicles}


@contextlib.contextmanager
def _fleet(n: int, ports: FleetPorts, speed: float = SPEED) -> Iterator[tuple[dict[str, Any], FleetEndpoints]]:
    """A live fleet of ``n`` commander vehicles (:func:`fleet_config`) served by one FleetEndpoints."""
    from cufund.apps.mavlink.fleet_live import LiveFleet

    live = LiveFleet(fleet_config(n), speed=speed)
    fleet = None
    try:
        fleet = FleetEndpoints(live.vehicles, ports).start()
        yield live.vehicles, fleet
    finally:
        if fleet is not None:
            fleet.close()
        live.stop()


def test_each_vehicle_is_its_own_system_on_the_shared_ground_station_port():
    port = free_port()
    gcs = Gcs(port)
    try:
        with _fleet(2, FleetPorts(gcs=f"udpout:127.0.0.1:{port}", api=None, px4_local_ports=False)) as (runs, fleet):
            assert [fleet.system_id(n) for n in ("uav1", "uav2")] == [1, 2]
            seen: set[int] = set()
            for _ in range(40):
                seen.add(gcs.recv("HEARTBEAT", 10.0).get_srcSystem())
                if len(seen) == 2:
                    break
            assert seen == {1, 2}
            assert len(gcs.conn.clients) == 2  # two instances, two source addresses (pymavlink answers each)
            # arm vehicle 2: the command goes to both sockets, only system 2 takes it and answers
            gcs.mav.command_long_send(2, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)  # COMPONENT_ARM_DISARM
            ack = gcs.recv("COMMAND_ACK", 10.0, cond=lambda m: m.command == 400)
            assert (ack.get_srcSystem(), ack.result) == (2, 0)
            assert runs["uav2"].wait_until(lambda t: t["armed"], 5.0)
            with pytest.raises(AssertionError):  # vehicle 1 answers nothing for system 2
                gcs.recv("COMMAND_ACK", 1.5, cond=lambda m: m.get_srcSystem() == 1)
            assert not runs["uav1"].telemetry()["armed"]
            gcs.mav.command_long_send(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)
            ack = gcs.recv("COMMAND_ACK", 10.0, cond=lambda m: m.command == 400)
            assert (ack.get_srcSystem(), ack.result) == (1, 0)
            assert runs["uav1"].wait_until(lambda t: t["armed"], 5.0)
    finally:
        gcs.close()


def test_fixed_local_ports_are_the_instances_and_a_taken_port_is_named():
    gcs_port, api_base = free_port(), _port_block(2)
    for p in (18570, 14580, 14581):  # the others the two vehicles take
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            try:
                probe.bind(("127.0.0.1", p))
            except OSError:
                pytest.skip(f"port {p} is in use on this machine (a PX4 instance?)")
    taken = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        taken.bind(("127.0.0.1", 18571))
    except OSError:
        taken.close()
        pytest.skip("port 18571 is in use on this machine (a PX4 instance?)")
    try:
        from cufund.apps.live import LiveRun

        runs = {n: LiveRun(OPEN_FIELD, start=False) for n in ("uav1", "uav2")}
        ports = FleetPorts(gcs=f"udpout:127.0.0.1:{gcs_port}", api=f"udpout:127.0.0.1:{api_base}")
        with pytest.raises(OSError, match="18571"):
            FleetEndpoints(runs, ports)
        taken.close()
        fleet = FleetEndpoints(runs, ports)
        try:
            local = [[lk.local_address[1] for lk in fleet.endpoint(n).links] for n in ("uav1", "uav2")]
            assert local == [
                [PX4_RC["gcs_local"], PX4_RC["api_local"]],
                [PX4_RC["gcs_local"] + 1, PX4_RC["api_local"] + 1],
            ]
            assert [lk.address.port for lk in fleet.endpoint("uav2").links] == [gcs_port, api_base + 1]
        finally:
            fleet.close()
    finally:
        taken.close()


mavsdk = pytest.importorskip("mavsdk_grpc")


async def _first(stream, cond, timeout: float):
    async def scan():
        async for x in stream:
            if cond(x):
                return x
        return None

    return await asyncio.wait_for(scan(), timeout)


def test_mavsdk_flies_two_vehicles_of_one_fleet():
    api = _port_block(2)
    grpc = [free_port(socket.SOCK_STREAM), free_port(socket.SOCK_STREAM)]
    exe = str(Path(mavsdk.__file__).parent / "bin" / "mavsdk_server")
    servers = [
        subprocess.Popen(
            [exe, "-p", str(grpc[i]), f"udpin://127.0.0.1:{api + i}"],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        for i in range(2)
    ]
    logs: list[str] = []
    try:
        ports = FleetPorts(gcs=None, api=f"udpout:127.0.0.1:{api}", px4_local_ports=False)
        with _fleet(2, ports) as (runs, _fleet_eps):

            async def fly(i: int, climb_m: float) -> tuple[int, float]:
                drone = mavsdk.System(mavsdk_server_address="127.0.0.1", port=grpc[i])
                await drone.connect()
                await _first(drone.core.connection_state(), lambda s: s.is_connected, 20)
                await _first(drone.telemetry.health(), lambda h: h.is_armable and h.is_global_position_ok, 15)
                await drone.action.arm()
                await _first(drone.telemetry.armed(), bool, 5)
                await drone.action.set_takeoff_altitude(climb_m)
                await drone.action.takeoff()
                up = await _first(drone.telemetry.position(), lambda p: p.relative_altitude_m > climb_m - 0.1, 30)
                await drone.action.land()
                await _first(drone.telemetry.in_air(), lambda a: not a, 40)
                return i, up.relative_altitude_m

            async def both() -> list:
                return await asyncio.gather(fly(0, 1.5), fly(1, 2.5))

            results = asyncio.run(asyncio.wait_for(both(), 120))
            assert [r[0] for r in results] == [0, 1]
            # each client flew its own vehicle: its own take-off altitude, and each landed where it started
            for name in ("uav1", "uav2"):
                tel = runs[name].telemetry()
                assert tel["landed"]
                assert tel["home_p_W"][0] == pytest.approx(3.0 * (name == "uav2"), abs=0.2)
            for r, climb in zip(results, (1.5, 2.5), strict=True):
                assert r[1] == pytest.approx(climb, abs=0.3)
    finally:
        logs = [kill(s) for s in servers]
    for i, log in enumerate(logs):
        assert "System discovered" in log, log[-2000:]
        assert f"(system ID: {i + 1})" in log, log[-2000:]  # server i found vehicle i, and only it
        assert f"system ID: {2 - i})" not in log, log[-2000:]


def test_mavproxy_lists_both_vehicles_of_cufund_serve(tmp_path):
    import yaml

    scenario = tmp_path / "fleet.yaml"
    scenario.write_text(yaml.safe_dump(fleet_config(2)))
    port = free_port()
    serve = cufund_serve(
        str(scenario), "--mavlink", f"udpout:127.0.0.1:{port}", "--api", "none", "--local-ports", "any",
        "--speed", str(SPEED), "--duration", "60",
    )  # fmt: skip
    proxy = mavproxy(port, tmp_path)
    try:
        out = ProcessOutput(proxy)
        seen = {out.expect(r"Detected vehicle [12]:1 on link 0", 40)}
        seen.add(out.expect(r"Detected vehicle [12]:1 on link 0", 30))
        assert seen == {"Detected vehicle 1:1 on link 0", "Detected vehicle 2:1 on link 0"}
        proxy.stdin.write("alllinks status\n")  # type: ignore[union-attr]
        proxy.stdin.flush()  # type: ignore[union-attr]
        out.expect(r"Sending to:\s+\{1, 2\}", 10)
    finally:
        kill(proxy, pumped=True)
        log = interrupt(serve)
    assert serve.returncode == 0, log
    for sysid in (1, 2):
        assert re.search(
            rf"MAVLink vehicle {sysid} \(uav{sysid}\): udpout:127.0.0.1:{port} \(local 127.0.0.1:\d+\)", log
        )
    assert "fleet of 2" in log


def test_serve_refuses_a_fleet_its_ports_cannot_hold(tmp_path):
    import yaml

    scenario = tmp_path / "fleet.yaml"
    scenario.write_text(yaml.safe_dump(fleet_config(3)))
    p = subprocess.run(
        [
            str(BIN / "cufund"),
            "serve",
            str(scenario),
            "--mavlink",
            "udpin:127.0.0.1:15000",
            "--api",
            "udpin:127.0.0.1:15001",
            "--duration",
            "1",
        ],  # fmt: skip
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 2
    assert "overlap" in p.stderr and "Traceback" not in p.stderr


def test_serve_uploads_a_plain_language_mission_each_client_downloads(tmp_path):
    import yaml

    pytest.importorskip("cufund.missions.mission_request")
    scenario = tmp_path / "fleet.yaml"
    scenario.write_text(yaml.safe_dump(fleet_config(2)))
    port = free_port()
    gcs = Gcs(port)
    serve = cufund_serve(
        str(scenario), "--mavlink", f"udpout:127.0.0.1:{port}", "--api", "none", "--local-ports", "any",
        "--duration", "60", "--mission", "zigzag with 3 rows of 5 waypoints at 3 m",
    )  # fmt: skip
    counts = {}
    try:
        for sysid in (1, 2):  # MAVLink's mission protocol: each system's count, then its items
            gcs.wait("HEARTBEAT", lambda m, s=sysid: m.get_srcSystem() == s, 40)
            gcs.mav.mission_request_list_send(sysid, 1)
            n = gcs.recv("MISSION_COUNT", 10, cond=lambda m, s=sysid: m.get_srcSystem() == s).count
            counts[sysid] = n
            for seq in range(n):
                gcs.mav.mission_request_int_send(sysid, 1, seq)
                it = gcs.recv(
                    "MISSION_ITEM_INT", 10, cond=lambda m, s=sysid, q=seq: m.get_srcSystem() == s and m.seq == q
                )
                assert it.frame == 6 and it.z == pytest.approx(3.0, abs=0.01)  # 3 m above home (relative frame)
            gcs.mav.mission_ack_send(sysid, 1, 0)
    finally:
        gcs.close()
        log = interrupt(serve)
    # the zigzag's 3 x 5 waypoints shared between the two vehicles, each client seeing its own share
    assert counts[1] + counts[2] == 15 and min(counts.values()) > 0
    assert f"uav1: mission of {counts[1]} waypoints uploaded (zigzag)" in log
    assert f"uav2: mission of {counts[2]} waypoints uploaded (zigzag)" in log


def test_serve_refuses_an_unsafe_mission_with_the_reason(tmp_path):
    import yaml

    pytest.importorskip("cufund.missions.mission_request")
    scenario = tmp_path / "fleet.yaml"
    scenario.write_text(yaml.safe_dump(fleet_config(2)))
    p = subprocess.run(
        [
            str(BIN / "cufund"),
            "serve",
            str(scenario),
            "--local-ports",
            "any",
            "--mavlink",
            "none",
            "--api",
            f"udpout:127.0.0.1:{free_port()}",
            "--duration",
            "1",
            "--mission",
            "zigzag with 3 rows of 5 waypoints at 0 m",
        ],  # fmt: skip
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 2 and "--mission: refused: below ground" in p.stderr, p.stderr
    p = subprocess.run(
        [str(BIN / "cufund"), "serve", "vehicle", "--duration", "1", "--mission", "go back home"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 2 and "--mission is for a fleet scenario" in p.stderr
