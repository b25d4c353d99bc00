"""The hand-packed lockstep codec (cufund.apps.mavlink.hil_codec) against pymavlink's own encoder and parser: every
frame byte for byte, the sequence shared with pymavlink-packed frames, and the controls parser taking only what
pymavlink would decode to the same values, leaving everything else to it."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import common as mavlink

from cufund.apps.mavlink.hil_codec import FrameWriter, take_controls


def _mav(seq=0):
    mav = mavlink.MAVLink(None, srcSystem=1, srcComponent=200)
    mav.seq = seq
    return mav


def _reference(mav, msg):
    """pymavlink's bytes for ``msg`` at mav's current sequence number."""
    return bytes(msg.pack(mav))


SENSOR_CASES = [
    (4000, 0.1, -0.2, -9.81, 0.01, -0.02, 0.03, 0.21, -0.01, 0.43, 1013.25, 0.0, 12.5, 15.0, 0x1FFF, 0),
    (123456789012, 1e-30, 3.4e38, -0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0),  # zeros trimmed
    (2**64 - 1, math.nan, math.inf, -math.inf, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 0x7, 2),
    (0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0),  # all zero: one byte stays
]
GPS_CASES = [
    (200000, 3, 473977418, 85455939, 488000, 120, 180, 35, 12, -30, 4, 35_00, 10, 0),
    (200000, 1, 0, 0, 0, 65535, 65535, 65535, 0, 0, 0, 65535, 0, 1),
    (1, 6, -(2**31), 2**31 - 1, -5, 0, 0, 0, -32768, 32767, 0, 0, 255, 0),
]


@pytest.mark.parametrize("args", SENSOR_CASES)
def test_hil_sensor_frames_are_pymavlinks_bytes(args):
    mav = _mav(seq=41)
    expected = _reference(_mav(seq=41), mav.hil_sensor_encode(*args))
    assert FrameWriter(mav).hil_sensor(*args) == expected
    assert mav.seq == 42


@pytest.mark.parametrize("args", GPS_CASES)
def test_hil_gps_frames_are_pymavlinks_bytes(args):
    mav = _mav(seq=7)
    expected = _reference(_mav(seq=7), mav.hil_gps_encode(*args))
    assert FrameWriter(mav).hil_gps(*args) == expected


def test_heartbeat_and_shared_sequence_wraps_like_mavlink():
    mav, ref = _mav(seq=254), _mav(seq=254)
    w = FrameWriter(mav)
    got = [
        w.heartbeat(0, 8, 0, 0, 0),
        w.pack(mav.command_ack_encode(511, 0, 0, 0, 1, 1)),
        w.heartbeat(2, 12, 129, 7, 4),
    ]
    want = []
    for msg in (
        ref.heartbeat_encode(0, 8, 0, 0, 0),
        ref.command_ack_encode(511, 0, 0, 0, 1, 1),
        ref.heartbeat_encode(2, 12, 129, 7, 4),
    ):
        want.append(_reference(ref, msg))
        ref.seq = (ref.seq + 1) % 256
    assert got == want
    assert [f[4] for f in got] == [254, 255, 0]  # the sequence byte
    parsed = _mav().parse_buffer(b"".join(got))  # and pymavlink reads them back with good CRCs
    assert [m.get_type() for m in parsed] == ["HEARTBEAT", "COMMAND_ACK", "HEARTBEAT"]


def test_a_signing_link_falls_back_to_pymavlink():
    mav = _mav()
    mav.signing.secret_key = bytes(range(32))
    mav.signing.sign_outgoing = True
    frame = FrameWriter(mav).hil_sensor(*SENSOR_CASES[0])
    assert frame[2] & mavlink.MAVLINK_IFLAG_SIGNED and len(frame) == 12 + frame[1] + 13


def _controls(peer, u, mode, time_usec=4000):
    values = list(u) + [0.0] * (16 - len(u))
    return bytes(peer.hil_actuator_controls_encode(time_usec, values, mode, 1).pack(peer))


@pytest.mark.parametrize(
    "u, mode",
    [([0.5, 0.25, -1.0, 1.0], 129), ([0.0, 0.0, 0.0, 0.0], 0), ([math.nan, 0.1, 0.2, 0.3], 128), ([0.7] * 16, 1)],
)
def test_controls_parse_to_what_pymavlink_decodes(u, mode):
    peer = _mav()
    frame = _controls(peer, u, mode)
    frames, rest = take_controls(frame + frame)
    ref = _mav().parse_buffer(frame)[0]
    assert rest == b"" and len(frames) == 2
    raw, got_u, got_mode = frames[0]
    assert raw == frame and got_mode == ref.mode
    np.testing.assert_array_equal(got_u, ref.controls[:4])  # float32 values, NaN included


def test_anything_else_is_left_for_pymavlink_from_its_first_byte():
    peer = _mav()
    c = _controls(peer, [0.5] * 4, 129)
    hb = bytes(peer.heartbeat_encode(2, 12, 0, 0, 0).pack(peer))
    bad = bytearray(c)
    bad[-1] ^= 0xFF
    frames, rest = take_controls(c + hb + c)
    assert len(frames) == 1 and rest == hb + c  # stops at the heartbeat, order kept
    for tail in (
        bytes(bad),
        c[:-1],
        b"\x00" + c,
        bytes(peer.hil_actuator_controls_encode(0, [0.5] * 16, 129, 1).pack(peer, force_mavlink1=True)),
    ):
        frames, rest = take_controls(c + tail)
        assert len(frames) == 1 and rest == tail
    rx = _mav()  # and pymavlink rejects the bad CRC the fast path left to it
    rx.robust_parsing = True
    assert [m.get_type() for m in rx.parse_buffer(bytes(bad)) or ()] != ["HIL_ACTUATOR_CONTROLS"]


def test_bridge_takes_controls_split_across_reads_and_after_other_messages():
    from cufund.apps.mavlink.px4_sim import Px4BridgeParams, Px4SimulatorBridge
    from cufund.scenarios import ScenarioConfig

    class _NoLink:
        def send(self, data):
            pass

        def recv(self, timeout):
            return None

        def close(self):
            pass

    config = ScenarioConfig.from_dict({"name": "codec", "vehicle": "iris", "seed": 1})
    bridge = Px4SimulatorBridge(config, _NoLink(), Px4BridgeParams(speed=None))
    peer = _mav()
    c = _controls(peer, [0.5] * 4, 129)
    hb = bytes(peer.heartbeat_encode(2, 12, 0, 0, 0).pack(peer))
    assert not bridge._handle(c[:20], 0.004)  # a partial frame waits in pymavlink's buffer
    assert bridge._handle(c[20:] + hb + c, 0.004)
    assert bridge.stats["controls"] == 2 and bridge.stats["heartbeats_received"] == 1
    assert bridge.armed
    np.testing.assert_allclose(sorted(bridge._command(0.004)), [600.0] * 4)  # iris: 1000 u + 100 rad/s
    assert not bridge._command(0.004).flags.writeable  # shared into messages as it is
