"""The vehicle endpoint under abuse: garbage, bad CRCs, unknown ids, nonsense values, a client that vanishes
mid-mission, a flood of 1000 COMMAND_LONG per second, a failing run. The vehicle keeps flying safely and the
endpoint's loop never dies."""

from __future__ import annotations

import math
import signal
import socket
import struct
import threading
import time

import numpy as np
import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink2

from cufund.apps.cli import main as cli_main
from mavlink_support import OPEN_FIELD, Gcs, free_port, vehicle

M = mavutil.mavlink


def _take_off(g, alt: float = 1.5) -> None:
    assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED
    assert (
        g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, 30.0 + alt).result
        == M.MAV_RESULT_ACCEPTED
    )
    g.wait("GLOBAL_POSITION_INT", lambda m: abs(m.relative_alt / 1e3 - alt) < 0.05, 20)


def test_garbage_bad_crc_unknown_ids_and_nonsense_values():
    with vehicle() as (live, ep, (g,)):
        dest = ep.links[0].local_address
        raw = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        codec = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
        good = codec.command_long_encode(
            1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, M.MAVLINK_MSG_ID_HEARTBEAT, 0, 0, 0, 0, 0, 0
        ).pack(codec)
        bad_crc = bytearray(good)
        bad_crc[-1] ^= 0xFF
        unknown = bytearray(good)
        unknown[7:10] = struct.pack("<I", 0xFFFF0)[:3]  # a message id no dialect knows
        rng = np.random.default_rng(0)
        datagrams = [bytes(bad_crc), bytes(unknown), good[:7], b"\xfd" * 300, b"", b"\xfe\x09"]
        datagrams += [rng.integers(0, 256, int(n), dtype=np.uint8).tobytes() for n in rng.integers(1, 400, 200)]
        datagrams += [b"\xfd" + rng.integers(0, 256, 40, dtype=np.uint8).tobytes() for _ in range(100)]
        for d in datagrams:
            raw.sendto(d, dest)
        raw.close()
        # values no vehicle can use: every one answered or counted, none crashes the loop
        nan = math.nan
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, nan).result == M.MAV_RESULT_DENIED
        assert g.command(M.MAV_CMD_DO_SET_MODE, nan, nan, nan).result == M.MAV_RESULT_DENIED
        assert g.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 1e12, 1e9).result == M.MAV_RESULT_UNSUPPORTED
        assert g.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, -5.0).result == M.MAV_RESULT_DENIED
        g.mav.param_set_send(1, 1, b"MPC_XY_P", nan, M.MAV_PARAM_TYPE_REAL32)
        assert g.recv("PARAM_VALUE", cond=lambda m: m.param_id == "MPC_XY_P").param_value == pytest.approx(3.0)
        g.mav.mission_request_int_send(1, 1, 65000, 0)
        assert g.recv("MISSION_ACK").type == M.MAV_MISSION_INVALID_SEQUENCE
        g.mav.mission_item_int_send(1, 1, 3, 0, 16, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0)  # no upload in progress: ignored
        for send_item in (  # a NaN latitude (legacy float item), a latitude beyond the pole: refused by name
            lambda: g.mav.mission_item_send(1, 1, 0, M.MAV_FRAME_GLOBAL, 16, 0, 1, 0, 0, 0, 0, nan, 114.2, 40, 0),
            lambda: g.mav.mission_item_int_send(
                1, 1, 0, M.MAV_FRAME_GLOBAL_INT, 16, 0, 1, 0, 0, 0, 0, 95 * 10**7, 1142068000, 40.0, 0
            ),
        ):
            g.mav.mission_count_send(1, 1, 1, 0)
            assert g.recv("MISSION_REQUEST_INT").seq == 0
            send_item()
            assert g.recv("MISSION_ACK").type == M.MAV_MISSION_INVALID_PARAM5_X
        assert live.telemetry()["mission"]["count"] == 0
        g.mav.set_position_target_local_ned_send(
            0, 1, 1, M.MAV_FRAME_LOCAL_NED, 0x9F8, nan, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
        )
        g.mav.set_attitude_target_send(0, 1, 1, 0, [0, 0, 0, 0], 0, 0, 0, 2.0)
        g.mav.command_long_send(
            1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION, 0, 0, 0, 0, 0, 0
        )
        g.recv("AUTOPILOT_VERSION")  # still answering
        assert ep.bad_data >= 300  # each garbage datagram counted
        assert ep.stats["setpoints_refused"] == 2
        assert ep.stats["handler_errors"] == 0
        assert ep._thread.is_alive() and live.running
        assert live.telemetry()["landed"] and not live.telemetry()["armed"]


def test_vanished_client_mid_mission_holds_then_lands():
    # open field: how far it flies before the (wall-clock) link-loss timeout depends on the machine's speed
    with vehicle(scenario=OPEN_FIELD, heartbeat_timeout_s=2.0) as (live, ep, (g,)):
        g.mav.param_set_send(1, 1, b"COM_DL_LOSS_T", 3.0, M.MAV_PARAM_TYPE_REAL32)  # land 3 s (sim) after the hold
        assert g.recv("PARAM_VALUE", cond=lambda m: m.param_id == "COM_DL_LOSS_T").param_value == 3.0
        _take_off(g, 1.5)
        p0 = np.array(live.telemetry()["p_W"])
        assert (
            live.submit({"command": "mission_upload", "items": [list(p0 + [20, 0, 0]), list(p0 + [20, 20, 0])]})
            .result(5)
            .result
            == "accepted"
        )
        assert g.command(M.MAV_CMD_MISSION_START).result == M.MAV_RESULT_ACCEPTED
        g.wait("LOCAL_POSITION_NED", lambda m: m.y - p0[0] > 1.0, 20)  # on its way east
        since = len(live.events)
        g.close()  # the client is gone: no heartbeat, nothing
        end = time.monotonic() + 45  # generous: a loaded machine runs the simulation slower
        while time.monotonic() < end and not any(e["message"] == "link lost" for e in live.events.since(since)):
            time.sleep(0.05)
        assert ep.link_lost
        modes = []
        end = time.monotonic() + 90  # hold, COM_DL_LOSS_T, descent: ~10 s simulated, slower on a loaded machine
        while time.monotonic() < end and not live.telemetry()["landed"]:
            mode = live.telemetry()["mode"]
            if not modes or modes[-1] != mode:
                modes.append(mode)
            time.sleep(0.02)
        assert modes[:2] == ["hold", "land"], modes  # hold first, then land after COM_DL_LOSS_T
        tel = live.telemetry()
        assert tel["landed"], (
            {k: tel.get(k) for k in ("t", "mode", "armed", "p_W", "truth_p_W", "v_W", "real_time_factor")},
            live.events.since(since),
        )
        p = np.array(live.telemetry()["truth_p_W"])
        assert 1.0 < p[0] - p0[0] < 15.0 and abs(p[1] - p0[1]) < 0.3  # it stopped where it was, short of the waypoint
        lost = next(e for e in live.events.since(since) if e["message"] == "link lost")
        land = next(e for e in live.events.since(since) if e["kind"] == "mode" and e.get("mode") == "land")
        assert land["t"] - lost["t"] == pytest.approx(3.0, abs=0.1)


def test_flood_of_1000_command_long_per_second():
    with vehicle() as (live, ep, (g,)):
        _take_off(g, 1.5)
        alt = []
        remove = live.add_listener(lambda tel: alt.append(tel["truth_p_W"][2]), 50.0)
        t0 = time.monotonic()
        sent = acks = 0

        def count_acks() -> int:
            n = 0
            while (m := g.conn.recv_match(type="COMMAND_ACK", blocking=False)) is not None:
                n += m.command == M.MAV_CMD_COMPONENT_ARM_DISARM
            return n

        # 2000 commands, at most 1000 per second, in back-to-back bursts of 10 (a loaded machine may send them more
        # slowly on average; each burst still arrives at once)
        while sent < 2000:
            for _ in range(10):
                g.mav.command_long_send(1, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
                sent += 1
            acks += count_acks()
            time.sleep(max(0.0, t0 + sent / 1000.0 - time.monotonic()))
        end = time.monotonic() + 30.0  # generous: the acks come from the commander's steps
        while acks < sent and time.monotonic() < end:
            g.heartbeat()
            acks += count_acks()
            time.sleep(0.01)
        remove()
        assert acks >= 0.95 * sent  # loopback UDP: (nearly) every command answered
        assert ep.stats["handler_errors"] == 0
        assert max(abs(a - alt[0]) for a in alt) < 0.05  # the hover did not notice
        assert g.command(M.MAV_CMD_NAV_LAND).result == M.MAV_RESULT_ACCEPTED  # and it still obeys


def test_a_failing_run_does_not_stop_the_loop():
    with vehicle() as (live, ep, (g,)):
        submit = live.submit

        def broken(cmd):
            raise RuntimeError("the run fell over")

        live.submit = broken
        g.mav.command_long_send(1, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
        end = time.monotonic() + 5
        while ep.stats["handler_errors"] == 0 and time.monotonic() < end:
            time.sleep(0.02)
        assert ep.stats["handler_errors"] == 1
        live.submit = submit
        assert g.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1).result == M.MAV_RESULT_ACCEPTED


def test_serve_cli_usage_errors_exit_2(capsys):
    assert cli_main(["serve", "--speed", "-1"]) == 2
    assert "--speed" in capsys.readouterr().err
    assert cli_main(["serve", "--mavlink", "tcp:1.2.3.4:5"]) == 2
    assert "udpout" in capsys.readouterr().err
    assert cli_main(["serve", "no_such_scenario", "--api", "none", "--duration", "1"]) == 2
    assert "no_such_scenario" in capsys.readouterr().err
    assert cli_main(["serve", "--mavlink", "none", "--api", "none"]) == 2
    for option in ("--telemetry-hz", "--heartbeat-timeout", "--link-loss-timeout"):  # named, before any run
        assert cli_main(["serve", option, "nan", "--api", "none"]) == 2
        assert f"{option} must be a number > 0" in capsys.readouterr().err


def test_serve_cli_warns_when_a_link_listens_beyond_loopback(capsys):
    port = free_port()
    handler = signal.getsignal(signal.SIGINT)
    assert cli_main(["serve", "--mavlink", f"udpin:0.0.0.0:{port}", "--api", "none", "--duration", "0.2"]) == 0
    out = capsys.readouterr()
    assert "0.0.0.0" in out.out and "other machines can command this vehicle" in out.err
    assert cli_main(["serve", "--mavlink", f"udpin:{port}", "--api", "none", "--duration", "0.2"]) == 0
    assert "warning" not in capsys.readouterr().err  # the default binds 127.0.0.1: no warning
    assert signal.getsignal(signal.SIGINT) is handler  # the caller's Ctrl-C handler is back


def test_serve_cli_sets_the_link_loss_timeout_and_exits_0():
    port = free_port()
    g = Gcs(port)
    rc: list[int] = []
    t = threading.Thread(
        target=lambda: rc.append(
            cli_main(
                [
                    "serve",
                    "vehicle",
                    "--mavlink",
                    f"udpout:127.0.0.1:{port}",
                    "--api",
                    "none",
                    "--speed",
                    "3",
                    "--duration",
                    "3",
                    "--link-loss-timeout",
                    "7",
                ]
            )
        )
    )
    t.start()
    try:
        g.recv("HEARTBEAT", 15)
        g.mav.param_request_read_send(1, 1, b"COM_DL_LOSS_T", -1)
        assert g.recv("PARAM_VALUE", cond=lambda m: m.param_id == "COM_DL_LOSS_T").param_value == 7.0
    finally:
        t.join(20)
        g.close()
    assert rc == [0]


def test_a_stalled_run_gets_no_mission_behind_the_clients_back():
    """The simulation does not answer (here: it never started): the upload is answered MAV_MISSION_ERROR and the
    queued plan is withdrawn, so the vehicle never flies a plan its operator was told had failed."""
    from cufund.apps.live import LiveRun
    from cufund.apps.mavlink.vehicle_endpoint import VehicleEndpoint

    port = free_port()
    g = Gcs(port)
    live = LiveRun("vehicle", start=False)
    ep = VehicleEndpoint(live, [f"udpout:127.0.0.1:{port}"])  # not started: the test turns its loop

    def spin_until(types: str) -> object:
        end = time.monotonic() + 15
        while time.monotonic() < end:
            ep.spin_once(0.05)
            m = g.conn.recv_match(type=types, blocking=False)
            if m is not None:
                return m
        raise AssertionError(f"no {types}")

    try:
        spin_until("HEARTBEAT")
        g.mav.mission_count_send(1, 1, 1, 0)
        assert spin_until("MISSION_REQUEST_INT").seq == 0
        g.mav.mission_item_int_send(
            1,
            1,
            0,
            M.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            M.MAV_CMD_NAV_WAYPOINT,
            0,
            1,
            0,
            0,
            0,
            math.nan,
            224196000,
            1142068000,
            1.0,
            0,
        )
        assert spin_until("MISSION_ACK").type == M.MAV_MISSION_ERROR
        live.commander.process_pending(0.0)  # the simulation wakes up: nothing of that upload is left to apply
        assert len(live.commander.mission) == 0 and ep.stats["handler_errors"] == 0
    finally:
        ep.close()
        live.stop()
        g.close()
