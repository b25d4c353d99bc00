"""The lockstep hot path's MAVLink 2 wire codec, by hand with :mod:`struct`: HIL_SENSOR, HIL_GPS and HEARTBEAT
frames out, HIL_ACTUATOR_CONTROLS frames in. pymavlink builds a message object, a header object and a byte
array per frame; at 250 round trips per simulated second (and thousands per wall second faster than real time)
that is most of the bridge's cost. Everything else still goes through pymavlink.

The bytes are pymavlink's own (tested byte for byte): the payload layout (``unpacker``) and CRC_EXTRA come from
pymavlink's message classes, trailing zero bytes of the payload are trimmed as MAVLink 2 does, and the CRC is
CRC-16/MCRF4XX over the frame after the magic byte, then CRC_EXTRA (``fastcrc``, which pymavlink uses too).
Unsigned frames only: a signed outgoing link falls back to pymavlink, a signed incoming frame is left to it.
"""

from __future__ import annotations

import re
import struct
from typing import Any

from fastcrc.crc16 import mcrf4xx
from pymavlink.dialects.v20 import common as mavlink

__all__ = ["MAVLINK2_MAGIC", "ControlsFrame", "FrameWriter", "scan_frames", "take_controls"]

MAVLINK2_MAGIC = 0xFD
_MAGIC = bytes((MAVLINK2_MAGIC,))
_HEADER = struct.Struct("<BBBBBBHB")  # after the magic: len, incompat, compat, seq, sysid, compid, msgid low 16, high 8
_CRC = struct.Struct("<H")
_HEARTBEAT = mavlink.MAVLink_heartbeat_message
_HIL_SENSOR = mavlink.MAVLink_hil_sensor_message
_HIL_GPS = mavlink.MAVLink_hil_gps_message
_CONTROLS = mavlink.MAVLink_hil_actuator_controls_message
_CONTROLS_ID = _CONTROLS.id  # 93
_CONTROLS_LEN = _CONTROLS.unpacker.size  # 81: time_usec, flags, controls[16], mode
_CONTROLS_EXTRA = bytes((_CONTROLS.crc_extra,))
_CONTROLS_UNPACK = struct.Struct("<8x8x4f48xB")  # controls[0..3] and mode; time_usec, flags, controls[4..] skipped
_ZEROS = bytes(_CONTROLS_LEN)
_EXTRA = {m.id: bytes((m.crc_extra,)) for m in (_HEARTBEAT, _HIL_SENSOR, _HIL_GPS)}  # CRC_EXTRA, precomputed


class FrameWriter:
    """Packs outgoing frames with the source ids and sequence counter of ``mav`` (a pymavlink ``MAVLink``),
    so the hand-packed frames and those pymavlink packs (:meth:`pack`) share one sequence."""

    def __init__(self, mav: Any) -> None:
        self.mav = mav

    def _frame(self, msg: Any, payload: bytes) -> bytes:
        mav = self.mav
        n = len(payload.rstrip(b"\x00")) or 1  # MAVLink 2 drops trailing zeros (at least one byte stays)
        seq = mav.seq
        mav.seq = (seq + 1) & 0xFF
        msg_id = msg.id
        body = (
            _HEADER.pack(n, 0, 0, seq, mav.srcSystem, mav.srcComponent, msg_id & 0xFFFF, msg_id >> 16) + payload[:n]
        )  # the CRC covers the frame after the magic byte, then CRC_EXTRA
        return _MAGIC + body + _CRC.pack(mcrf4xx(_EXTRA[msg_id], mcrf4xx(body, 0xFFFF)))

    def pack(self, msg: Any) -> bytes:
        """Any pymavlink message, packed by pymavlink at the next sequence number."""
        out = msg.pack(self.mav)
        self.mav.seq = (self.mav.seq + 1) & 0xFF
        return out

    @property
    def fast(self) -> bool:
        """False when the link signs its frames (then every frame goes through pymavlink)."""
        return not self.mav.signing.sign_outgoing

    def heartbeat(self, type_: int, autopilot: int, base_mode: int, custom_mode: int, system_status: int) -> bytes:
        if not self.fast:
            return self.pack(self.mav.heartbeat_encode(type_, autopilot, base_mode, custom_mode, system_status))
        payload = _HEARTBEAT.unpacker.pack(custom_mode, type_, autopilot, base_mode, system_status, 3)
        return self._frame(_HEARTBEAT, payload)

    def hil_sensor(
        self,
        time_usec: int,
        xacc: float,
        yacc: float,
        zacc: float,
        xgyro: float,
        ygyro: float,
        zgyro: float,
        xmag: float,
        ymag: float,
        zmag: float,
        abs_pressure: float,
        diff_pressure: float,
        pressure_alt: float,
        temperature: float,
        fields_updated: int,
        id_: int,
    ) -> bytes:
        fields = (
            time_usec,
            xacc,
            yacc,
            zacc,
            xgyro,
            ygyro,
            zgyro,
            xmag,
            ymag,
            zmag,
            abs_pressure,
            diff_pressure,
            pressure_alt,
            temperature,
            fields_updated,
            id_,
        )  # declared order, which is also HIL_SENSOR's wire order (its fields are sorted by size already)
        if not self.fast:
            return self.pack(self.mav.hil_sensor_encode(*fields))
        return self._frame(_HIL_SENSOR, _HIL_SENSOR.unpacker.pack(*fields))

    def hil_gps(
        self,
        time_usec: int,
        fix_type: int,
        lat: int,
        lon: int,
        alt: int,
        eph: int,
        epv: int,
        vel: int,
        vn: int,
        ve: int,
        vd: int,
        cog: int,
        satellites_visible: int,
        id_: int,
        yaw: int = 0,
    ) -> bytes:
        if not self.fast:
            return self.pack(
                self.mav.hil_gps_encode(
                    time_usec, fix_type, lat, lon, alt, eph, epv, vel, vn, ve, vd, cog, satellites_visible, id_, yaw
                )
            )
        payload = _HIL_GPS.unpacker.pack(
            time_usec, lat, lon, alt, eph, epv, vel, vn, ve, vd, cog, fix_type, satellites_visible, id_, yaw
        )
        return self._frame(_HIL_GPS, payload)


ControlsFrame = tuple[bytes, tuple[float, float, float, float], int]
"""One HIL_ACTUATOR_CONTROLS frame taken off the wire: (its bytes, controls[0..3], mode)."""


def take_controls(data: bytes) -> tuple[list[ControlsFrame], bytes]:
    """Splits the leading whole, unsigned, CRC-valid MAVLink 2 HIL_ACTUATOR_CONTROLS frames off ``data``:
    (those frames, the rest). The rest starts at the first byte that is anything else (another message, a
    MAVLink 1 or signed frame, a partial frame, a bad CRC, noise) and is for pymavlink's parser."""
    frames: list[ControlsFrame] = []
    i, n = 0, len(data)
    while (
        n - i >= 12
        and data[i] == MAVLINK2_MAGIC
        and data[i + 2] == 0
        and data[i + 7] == _CONTROLS_ID
        and data[i + 8] == 0
        and data[i + 9] == 0
    ):
        plen = data[i + 1]
        end = i + 10 + plen
        if plen > _CONTROLS_LEN or plen == 0 or end + 2 > n:
            break
        if mcrf4xx(_CONTROLS_EXTRA, mcrf4xx(data[i + 1 : end], 0xFFFF)) != data[end] | data[end + 1] << 8:
            break
        payload = data[i + 10 : end]
        if plen < _CONTROLS_LEN:
            payload += _ZEROS[plen:]
        c0, c1, c2, c3, mode = _CONTROLS_UNPACK.unpack(payload)
        frames.append((data[i : end + 2], (c0, c1, c2, c3), mode))
        i = end + 2
    return frames, data[i:] if i else data


_STARTS = re.compile(b"[\xfd\xfe]")  # MAVLink 2 and MAVLink 1 frame starts
_OK, _SHORT, _BAD = 0, 1, 2


def _frame_at(buf: bytes, j: int) -> tuple[int, int]:
    """(_OK, end) when a whole CRC-valid frame of a known message starts at ``buf[j]``; (_SHORT, 0) when one may
    start there but the bytes end first; (_BAD, 0) when none starts there."""
    n = len(buf)
    if buf[j] == MAVLINK2_MAGIC:
        if n - j < 10:
            return _SHORT, 0
        plen, incompat = buf[j + 1], buf[j + 2]
        if incompat & ~1:
            return _BAD, 0
        msg_id = buf[j + 7] | buf[j + 8] << 8 | buf[j + 9] << 16
        end = j + 12 + plen + (13 if incompat & 1 else 0)
        crc_end = j + 10 + plen
    else:  # MAVLink 1
        if n - j < 6:
            return _SHORT, 0
        plen, msg_id = buf[j + 1], buf[j + 5]
        end = j + 8 + plen
        crc_end = j + 6 + plen
    cls = mavlink.mavlink_map.get(msg_id)
    if cls is None:
        return _BAD, 0
    if end > n:
        return _SHORT, 0
    if mcrf4xx(bytes((cls.crc_extra,)), mcrf4xx(buf[j + 1 : crc_end], 0xFFFF)) != buf[crc_end] | buf[crc_end + 1] << 8:
        return _BAD, 0
    return _OK, end


def scan_frames(buf: bytes) -> tuple[list[bytes], int, bytes]:
    """Whole, CRC-valid MAVLink frames (of messages the dialect knows) in a byte stream, resynchronising past
    anything else byte by byte: a false frame start in noise never swallows the real frame behind it (unlike a
    parser that trusts the first length byte it meets). Returns (frames, bad pieces skipped, rest): ``rest`` is
    a frame start cut off by the end of ``buf``, to be completed by what comes next (it is given up as noise
    when a whole frame follows it in ``buf``)."""
    frames: list[bytes] = []
    bad = 0
    i, n = 0, len(buf)
    while i < n:
        m = _STARTS.search(buf, i)
        j = m.start() if m is not None else n
        if j > i:
            bad += 1  # bytes that start no frame
        if j == n:
            break
        status, end = _frame_at(buf, j)
        if status == _OK:
            frames.append(bytes(buf[j:end]))
            i = end
            continue
        if status == _SHORT and not any(_frame_at(buf, k.start())[0] == _OK for k in _STARTS.finditer(buf, j + 1)):
            return frames, bad, bytes(buf[j:])
        bad += 1  # a false start: look again from the next byte
        i = j + 1
    return frames, bad, b""
