"""Protocol state of the MAVLink vehicle endpoint and the PX4 bridge under clients that interfere with each other
(all on 127.0.0.1): concurrent mission uploads, per-link message intervals, a stray packet on a udpin link,
out-of-range parameters, unknown mission commands, noise before PX4's controls, a second simulator client and a
reset connection. Each check failed on the endpoint and bridge before they kept this state."""

from __future__ import annotations

import logging
import math
import socket
import struct
import threading
import time

import numpy as np
import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as M

from cufund.apps.mavlink.frames import GeodeticOrigin
from cufund.apps.mavlink.mission_protocol import MissionProtocol
from cufund.apps.mavlink.px4_harness import Px4Harness
from cufund.apps.mavlink.px4_links import TcpServerLink
from cufund.apps.mavlink.px4_sim import Px4BridgeParams, Px4SimulatorBridge
from cufund.scenarios import ScenarioConfig
from cufund.sensors.gps import GpsParams
from mavlink_support import free_port, px4_sim_cli, vehicle

HOME = GeodeticOrigin.from_geo_point(GpsParams().home)


def _item(g, seq: int, z: float, command: int = M.MAV_CMD_NAV_WAYPOINT) -> None:
    lat, lon, _ = HOME.enu_to_lla(np.array([0.0, 0.0, 0.0]))
    g.mav.mission_item_int_send(
        1,
        1,
        seq,
        M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        command,
        0,
        1,
        0,
        0,
        0,
        math.nan,
        round(lat * 1e7),
        round(lon * 1e7),
        z,
        0,
    )


def _download(g) -> list:
    g.mav.mission_request_list_send(1, 1, 0)
    n = g.recv("MISSION_COUNT").count
    items = []
    for seq in range(n):
        g.mav.mission_request_int_send(1, 1, seq, 0)
        items.append(g.recv("MISSION_ITEM_INT", cond=lambda m, s=seq: m.seq == s))
    return items


# --- missions ------------------------------------------------------------------------------------------------


def test_two_clients_uploading_at_once_do_not_mix_their_items():
    with vehicle(links=2) as (_live, ep, (a, b)):
        b.mav.srcSystem = 254  # another ground station
        a.mav.mission_count_send(1, 1, 3, 0)
        assert a.recv("MISSION_REQUEST_INT").seq == 0
        _item(a, 0, 1.0)
        assert a.recv("MISSION_REQUEST_INT", cond=lambda m: m.seq == 1).seq == 1
        b.mav.mission_count_send(1, 1, 3, 0)  # B starts its own upload in the middle of A's
        ack = b.recv(["MISSION_ACK", "MISSION_REQUEST_INT"])
        assert ack.get_type() == "MISSION_ACK" and ack.type == M.MAV_MISSION_DENIED  # busy, as PX4
        _item(b, 1, 7.0)  # and pushes an item into A's transfer
        assert b.recv("MISSION_ACK").type == M.MAV_MISSION_DENIED
        b.mav.mission_clear_all_send(1, 1, 0)  # or clears under it
        assert b.recv("MISSION_ACK").type == M.MAV_MISSION_DENIED
        for seq in (1, 2):
            if seq == 2:
                assert a.recv("MISSION_REQUEST_INT", cond=lambda m: m.seq == 2).seq == 2
            _item(a, seq, 1.0 + seq)
        assert a.recv("MISSION_ACK").type == M.MAV_MISSION_ACCEPTED
        assert [it.z for it in _download(a)] == [1.0, 2.0, 3.0]  # A's plan, whole
        assert ep.missions.partner is None
        b.mav.mission_count_send(1, 1, 1, 0)  # A is done: B's turn
        assert b.recv("MISSION_REQUEST_INT").seq == 0


class _Msgs:
    """MAVLink messages as they arrive from (sysid, compid): packed by one codec, parsed by another."""

    def __init__(self) -> None:
        self.rx = M.MAVLink(None)

    def __call__(self, src: tuple[int, int], build):
        tx = M.MAVLink(None, srcSystem=src[0], srcComponent=src[1])
        return self.rx.parse_char(build(tx).pack(tx))


def test_a_transfer_times_out_after_pxs_five_silent_seconds_and_frees_the_vehicle():
    msgs, acks, requests = _Msgs(), [], []

    def send(factory):
        m = factory(M.MAVLink(None))
        (acks if m.get_type() == "MISSION_ACK" else requests).append(m)

    proto = MissionProtocol(lambda items: M.MAV_MISSION_ACCEPTED, lambda: True, lambda seq: True, lambda: -1)
    a, b = (250, 190), (251, 190)
    proto.handle(msgs(a, lambda mav: mav.mission_count_encode(1, 1, 2, 0)), send, now=100.0)
    for t in np.arange(100.25, 105.0, 0.25):  # requests repeated every 250 ms, PX4's retry time
        proto.poll(t)
    assert not acks and len(requests) == 1 + 19 and {r.target_system for r in requests} == {250}
    proto.handle(msgs(b, lambda mav: mav.mission_count_encode(1, 1, 1, 0)), send, now=104.9)
    assert [(k.type, k.target_system) for k in acks] == [(M.MAV_MISSION_DENIED, 251)]  # still A's transfer
    proto.poll(105.0)
    assert len(acks) == 1 and requests[-1].target_system == 250
    proto.poll(105.01)  # 5 s without a word from A: PX4's MAVLINK_MISSION_PROTOCOL_TIMEOUT_DEFAULT
    assert (acks[-1].type, acks[-1].target_system) == (M.MAV_MISSION_OPERATION_CANCELLED, 250)
    proto.handle(msgs(b, lambda mav: mav.mission_count_encode(1, 1, 1, 0)), send, now=105.1)
    assert requests[-1].target_system == 251 and proto.partner == b


def test_a_transfer_is_locked_to_its_link_as_well_as_to_its_partners_ids():
    """Two ground stations with the same default ids (QGroundControl's 255/190) on two links: the second one's
    MISSION_COUNT and items are refused while the first one's transfer is under way, and the first one's plan
    arrives whole."""
    msgs, sent = _Msgs(), {"one": [], "two": []}

    def sender(name):
        return lambda factory: sent[name].append(factory(M.MAVLink(None)))

    accepted = []
    proto = MissionProtocol(
        lambda items: accepted.append(items) or M.MAV_MISSION_ACCEPTED, lambda: True, lambda seq: True, lambda: -1
    )
    gcs, one, two = (255, 190), object(), object()
    proto.handle(msgs(gcs, lambda mav: mav.mission_count_encode(1, 1, 1, 0)), sender("one"), now=1.0, link=one)
    proto.handle(msgs(gcs, lambda mav: mav.mission_count_encode(1, 1, 2, 0)), sender("two"), now=1.1, link=two)
    assert [m.type for m in sent["two"] if m.get_type() == "MISSION_ACK"] == [M.MAV_MISSION_DENIED]

    def item(mav, z):
        return mav.mission_item_int_encode(
            1, 1, 0, M.MAV_FRAME_LOCAL_ENU, M.MAV_CMD_NAV_WAYPOINT, 0, 1, 0, 0, 0, 0, 0, 0, z, 0
        )

    proto.handle(msgs(gcs, lambda mav: item(mav, 9.0)), sender("two"), now=1.2, link=two)  # refused: other link
    proto.handle(msgs(gcs, lambda mav: item(mav, 1.5)), sender("one"), now=1.3, link=one)
    assert [m.type for m in sent["one"] if m.get_type() == "MISSION_ACK"] == [M.MAV_MISSION_ACCEPTED]
    assert len(accepted) == 1 and len(accepted[0]) == 1


def test_a_mission_item_with_an_unknown_command_is_unsupported():
    with vehicle() as (live, _ep, (g,)):
        g.mav.mission_count_send(1, 1, 2, 0)
        assert g.recv("MISSION_REQUEST_INT").seq == 0
        _item(g, 0, 1.5)
        assert g.recv("MISSION_REQUEST_INT", cond=lambda m: m.seq == 1).seq == 1
        _item(g, 1, 1.5, command=12345)  # no MAV_CMD has this number
        assert g.recv("MISSION_ACK").type == M.MAV_MISSION_UNSUPPORTED
        assert _download(g) == [] and live.telemetry()["mission"]["count"] == 0


# --- message intervals -----------------------------------------------------------------------------------------


def test_message_intervals_are_per_link_and_non_finite_ones_are_refused():
    with vehicle(links=2) as (_live, _ep, (a, b)):
        for msg_id, interval in (
            (M.MAVLINK_MSG_ID_HEARTBEAT, math.nan),
            (M.MAVLINK_MSG_ID_HEARTBEAT, math.inf),
            (M.MAVLINK_MSG_ID_HEARTBEAT, -1.0),
        ):
            assert a.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, interval).result == M.MAV_RESULT_FAILED
        for interval in (math.nan, math.inf, -math.inf, -5.0):
            assert (
                a.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_ATTITUDE, interval).result
                == M.MAV_RESULT_DENIED
            )
        assert a.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, math.nan, 1e5).result == M.MAV_RESULT_DENIED
        a.drain()
        b.drain()
        for g in (a, b):  # the heartbeat still goes out on every link, ...
            g.recv("HEARTBEAT", 3.0)
            g.recv("ATTITUDE", 2.0)  # ... and ATTITUDE at its rate
        assert (
            a.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, -1).result
            == M.MAV_RESULT_ACCEPTED
        )
        a.drain()
        b.drain()
        b.recv("GLOBAL_POSITION_INT", 2.0)  # the other link keeps its stream
        with pytest.raises(AssertionError):
            a.recv("GLOBAL_POSITION_INT", 1.0)  # only A's stopped


# --- udpin ---------------------------------------------------------------------------------------------------------


def test_udpin_keeps_its_first_peer_against_a_stray_packet():
    port = free_port()
    with vehicle(links=0, extra_links=[f"udpin:127.0.0.1:{port}"]) as (_live, ep, _):
        gcs = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, dialect="common")
        stray = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        stray.bind(("127.0.0.1", 0))
        stray.settimeout(0.5)
        try:
            gcs.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            assert gcs.recv_match(type="HEARTBEAT", blocking=True, timeout=5) is not None
            mav = M.MAVLink(None, srcSystem=66, srcComponent=1)
            gcs.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)  # the peer, heard just now
            stray.sendto(
                mav.heartbeat_encode(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0).pack(mav), ("127.0.0.1", port)
            )
            with pytest.raises(socket.timeout):
                stray.recv(65536)  # nothing goes to the stray sender, ...
            while gcs.recv_match(blocking=False) is not None:
                pass
            assert gcs.recv_match(type="HEARTBEAT", blocking=True, timeout=3) is not None  # ... the GCS keeps it
            assert ep.links[0].stats.foreign == 1
            ep.links[0].peer_timeout_s = 0.2  # the GCS falls silent for longer than this: the next one is the peer
            time.sleep(0.4)
            stray.sendto(
                mav.heartbeat_encode(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0).pack(mav), ("127.0.0.1", port)
            )
            stray.settimeout(5.0)
            assert stray.recv(65536)
        finally:
            stray.close()
            gcs.close()


def test_udpin_does_not_take_a_sender_of_garbage_as_its_peer():
    """A datagram that holds no CRC-valid MAVLink (a port scan, noise) before the ground station's first packet does
    not become the peer: the ground station does, and gets the stream."""
    port = free_port()
    with vehicle(links=0, extra_links=[f"udpin:127.0.0.1:{port}"]) as (_live, ep, _):
        stray = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        stray.bind(("127.0.0.1", 0))
        stray.settimeout(0.5)
        gcs = None
        try:
            stray.sendto(b"\xfd\x09garbage, not MAVLink" * 3, ("127.0.0.1", port))
            deadline = time.monotonic() + 5.0
            while ep.links[0].stats.bad_data == 0 and time.monotonic() < deadline:
                time.sleep(0.02)
            assert ep.links[0].stats.bad_data >= 1 and ep.links[0].peer is None
            gcs = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255, dialect="common")
            gcs.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            assert gcs.recv_match(type="HEARTBEAT", blocking=True, timeout=5) is not None
            with pytest.raises(socket.timeout):
                stray.recv(65536)
        finally:
            stray.close()
            if gcs is not None:
                gcs.close()


# --- parameters ------------------------------------------------------------------------------------------------


def _all_params(g) -> dict[str, float]:
    g.mav.param_request_list_send(1, 1)
    first = g.recv("PARAM_VALUE")
    values = {first.param_id: first.param_value}
    while len(values) < first.param_count:
        m = g.recv("PARAM_VALUE", 3)
        values[m.param_id] = m.param_value
    return values


def test_out_of_range_parameters_are_not_applied():
    with vehicle() as (live, _ep, (g,)):
        values = _all_params(g)
        rate = next(c for c in live.simulator.components if type(c).__name__ == "RateController")
        for name, bad in (
            ("MC_ROLLRATE_P", 0.0),
            ("MIS_TAKEOFF_ALT", 1e38),
            ("MPC_TILTMAX_AIR", 95.0),
            ("NAV_ACC_RAD", -1.0),
            ("MPC_THR_MAX", 1.5),
        ):
            g.mav.param_set_send(1, 1, name.encode(), bad, M.MAV_PARAM_TYPE_REAL32)
            got = {}
            while len(got) < 2:  # a warning naming the parameter, and the value in force
                m = g.recv(
                    ["PARAM_VALUE", "STATUSTEXT"],
                    cond=lambda m, n=name: n in (m.param_id if m.get_type() == "PARAM_VALUE" else m.text),
                )
                got[m.get_type()] = m
            assert got["PARAM_VALUE"].param_value == pytest.approx(values[name]), name
        assert rate.gains.roll_p == pytest.approx(values["MC_ROLLRATE_P"])
        ack = live.submit({"command": "get_params"}).result(timeout=10)
        assert ack.data["MIS_TAKEOFF_ALT"] == pytest.approx(values["MIS_TAKEOFF_ALT"])
        g.mav.param_set_send(1, 1, b"MIS_TAKEOFF_ALT", 3.0, M.MAV_PARAM_TYPE_REAL32)  # in range: applied
        assert g.recv("PARAM_VALUE", cond=lambda m: m.param_id == "MIS_TAKEOFF_ALT").param_value == 3.0

    from cufund.apps.mavlink.param_protocol import PX4_BOUNDS

    for name, value in values.items():  # the scenario's own values are all settable
        lo, hi = PX4_BOUNDS.get(name, (-math.inf, math.inf))
        assert lo <= value <= hi, name


# --- the PX4 bridge ------------------------------------------------------------------------------------------

STEP_US = 4000


def _bridge(params):
    config = ScenarioConfig.from_dict({"name": "px4_state", "vehicle": "iris", "seed": 1, "duration": 60.0})
    bridge = Px4SimulatorBridge(config, TcpServerLink("127.0.0.1", 0), params)
    bridge.simulator.vehicle.hover(np.array([0.0, 0.0, 10.0]))
    outcome: dict = {}

    def run():
        try:
            outcome["result"] = bridge.run(duration=30.0, connect_timeout=10.0)
        except BaseException as e:
            outcome["error"] = e

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return bridge, thread, outcome


def test_noise_before_controls_does_not_cost_the_controls():
    params = Px4BridgeParams(speed=None, wait_first_controls=True, controls_timeout_s=3.0)
    bridge, thread, _ = _bridge(params)
    px4 = Px4Harness.tcp("127.0.0.1", bridge.port_number)
    try:
        for k in range(6):
            s = px4.step()
            # a false frame start whose length byte (255) reaches over the real controls frame behind it
            noise = [b"\x00\xfd\xff\x00\x00\x01\x01\x01\x00\x00\x00", b"junk\xfd", b"\xfe\x40" + bytes(10)][k % 3]
            frame = px4.mav.hil_actuator_controls_encode(s.sensor.time_usec, [0.0] * 16, 0, 1).pack(px4.mav)
            px4.mav.seq = (px4.mav.seq + 1) % 256
            if k == 4:  # noise and frame arriving in separate reads
                px4._write(noise)
                time.sleep(0.05)
                px4._write(frame)
            else:
                px4._write(noise + frame)
        px4.step()
        assert bridge.stats["controls"] == 6 and bridge.stats["controls_timeouts"] == 0
        assert bridge.stats["bad_packets"] >= 6
    finally:
        px4.close()
        thread.join(10.0)
        bridge.close()


def test_a_second_simulator_client_is_refused_with_a_message(caplog):
    params = Px4BridgeParams(speed=None, wait_first_controls=True)
    bridge, thread, _ = _bridge(params)
    px4 = Px4Harness.tcp("127.0.0.1", bridge.port_number)
    second = None
    try:
        s = px4.step()
        second = socket.create_connection(("127.0.0.1", bridge.port_number), timeout=5.0)
        with caplog.at_level(logging.WARNING, logger="cufund.px4_sim"):
            for _ in range(260):  # past the next simulated second, when the bridge looks at its door
                px4.controls([0.0] * 4, armed=False, time_usec=s.sensor.time_usec)
                s = px4.step()
            got = b""
            second.settimeout(5.0)
            while chunk := second.recv(4096):
                got += chunk
        assert got == b"cufund px4-sim: already serving a PX4 connection; this one is refused\n"
        assert any("refused a second simulator connection" in r.getMessage() for r in caplog.records)
        assert bridge.link.refused == 1 and bridge.link.connected  # the first PX4 is still served
    finally:
        if second is not None:
            second.close()
        px4.close()
        thread.join(10.0)
        bridge.close()


def _reset(sock: socket.socket) -> None:
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))  # close = RST
    sock.close()


def test_a_reset_connection_ends_the_run_as_a_failure():
    params = Px4BridgeParams(speed=None, wait_first_controls=True)
    bridge, thread, outcome = _bridge(params)
    px4 = Px4Harness.tcp("127.0.0.1", bridge.port_number)
    try:
        for _ in range(5):
            s = px4.step()
            px4.controls([0.0] * 4, armed=False, time_usec=s.sensor.time_usec)
        sock = px4._write.__self__  # the harness's socket (its sendall)
        _reset(sock)
        thread.join(10.0)
        assert not thread.is_alive()
        result = outcome["result"]
        assert result.status.value == "aborted" and "reset" in result.message.lower()
    finally:
        thread.join(10.0)
        bridge.close()


def test_cli_exits_non_zero_with_the_reason_after_a_reset(capsys):
    thread, code, port = px4_sim_cli(30)
    px4 = Px4Harness.tcp("127.0.0.1", port, timeout=20.0)
    s = px4.step(timeout=10.0)
    px4.controls([0.0] * 4, armed=False, time_usec=s.sensor.time_usec)
    px4.step(timeout=10.0)
    _reset(px4._write.__self__)
    thread.join(30.0)
    assert not thread.is_alive()
    assert code["exit"] == 1
    err = capsys.readouterr().err
    assert "Connection reset by peer" in err
