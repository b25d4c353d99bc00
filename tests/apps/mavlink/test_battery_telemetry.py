"""The battery over MAVLink: BATTERY_STATUS and SYS_STATUS carry the power module's reading in MAVLink's units
(mV, cA, mAh, %), decoded by pymavlink's own parser; over a live ``vehicle.battery`` run they follow the run's
telemetry, as pymavlink and MAVSDK read them."""

from __future__ import annotations

import asyncio
import math
import socket
import subprocess
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import common as mavlink2

from cufund.apps.mavlink import telemetry_streams as ts
from cufund.scenarios import load_scenario
from mavlink_support import free_port, vehicle

M = mavlink2
READING = {"voltage_v": 15.234, "current_a": 17.86, "remaining": 0.634, "consumed_mah": 311.4, "cells": 4}


def _roundtrip(msg_fn, snapshot: ts.VehicleSnapshot):
    """Encodes with one MAVLink object, decodes the bytes with another (pymavlink's parser, not ours)."""
    tx = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    rx = mavlink2.MAVLink(None)
    buf = msg_fn(tx, snapshot).pack(tx)
    msgs = rx.parse_buffer(buf)
    assert msgs is not None and len(msgs) == 1
    return msgs[0]


def _snapshot(battery: dict | None) -> ts.VehicleSnapshot:
    tel = {"t": 3.0, "p_W": [0, 0, 1], "armed": True, "landed": False, "mode": "hold"}
    if battery is not None:
        tel["battery"] = battery
    return ts.VehicleSnapshot.from_telemetry(tel)


def test_battery_status_carries_the_reading_in_mavlink_units() -> None:
    m = _roundtrip(ts.encode_battery_status, _snapshot(READING))
    assert m.get_type() == "BATTERY_STATUS"
    assert list(m.voltages[:4]) == [round(15234 / 4)] * 4 and list(m.voltages[4:]) == [65535] * 6
    assert m.current_battery == 1786  # cA
    assert m.current_consumed == 311  # mAh
    assert m.battery_remaining == 63
    assert m.type == M.MAV_BATTERY_TYPE_LIPO and m.temperature == 32767  # INT16_MAX: unknown


def test_sys_status_battery_fields() -> None:
    m = _roundtrip(ts.encode_sys_status, _snapshot(READING))
    assert (m.voltage_battery, m.current_battery, m.battery_remaining) == (15234, 1786, 63)


def test_without_a_battery_the_old_full_pack_is_reported() -> None:
    m = _roundtrip(ts.encode_sys_status, _snapshot(None))
    assert (m.voltage_battery, m.current_battery, m.battery_remaining) == (16200, -1, 100)
    b = _roundtrip(ts.encode_battery_status, _snapshot(None))
    assert b.battery_remaining == 100 and b.current_battery == -1
    bad = _snapshot({"voltage_v": math.nan, "current_a": 1.0, "remaining": 1.0, "consumed_mah": 0, "cells": 4})
    assert bad.battery is None  # a reading with a non-finite number is not reported


def _battery_scenario():
    return load_scenario(
        "vehicle", ["vehicle.battery.cells=4", "vehicle.battery.capacity_mah=850", "vehicle.battery.avionics_w=12"]
    )


def test_live_run_streams_its_battery_over_pymavlink() -> None:
    with vehicle(scenario=_battery_scenario()) as (live, ep, (g,)):
        ep.link_intervals[ep.links[0]]["BATTERY_STATUS"] = 0.1  # 10 Hz for the test
        b = g.recv("BATTERY_STATUS", 10.0)
        s = g.recv("SYS_STATUS", 10.0)
        tel = live.telemetry()["battery"]
        assert tel["cells"] == 4
        # the pack at rest on the pad: ~4 x 4.10 V, a small avionics current, full
        assert sum(b.voltages[:4]) / 1e3 == pytest.approx(tel["voltage_v"], abs=0.1)
        assert list(b.voltages[4:]) == [65535] * 6
        assert s.voltage_battery / 1e3 == pytest.approx(tel["voltage_v"], abs=0.1)
        assert s.current_battery / 100 == pytest.approx(12.0 / tel["voltage_v"], abs=0.5)
        assert s.battery_remaining == 100 and b.battery_remaining == 100


mavsdk = pytest.importorskip("mavsdk_grpc")


def test_mavsdk_reads_the_battery() -> None:
    api, grpc = free_port(), free_port(socket.SOCK_STREAM)
    server = subprocess.Popen(
        [str(Path(mavsdk.__file__).parent / "bin" / "mavsdk_server"), "-p", str(grpc), f"udpin://127.0.0.1:{api}"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        with vehicle(links=0, extra_links=[f"udpout:127.0.0.1:{api}"], scenario=_battery_scenario()) as (live, _, _):

            async def read():
                drone = mavsdk.System(mavsdk_server_address="127.0.0.1", port=grpc)
                await drone.connect()

                async def first():
                    async for bat in drone.telemetry.battery():
                        if bat.voltage_v > 1.0:
                            return bat
                    return None

                return await asyncio.wait_for(first(), 30)

            bat = asyncio.run(read())
            tel = live.telemetry()["battery"]
            assert bat.voltage_v == pytest.approx(tel["voltage_v"], abs=0.1)
            assert bat.remaining_percent == pytest.approx(100.0, abs=1.0)
    finally:
        server.terminate()
        try:
            server.wait(5)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait(5)
