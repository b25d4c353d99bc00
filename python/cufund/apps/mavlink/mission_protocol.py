"""The MAVLink mission protocol (vehicle side): upload, download, clear, set current.

Upload: MISSION_COUNT -> MISSION_REQUEST_INT(seq) for each item -> MISSION_ITEM_INT -> MISSION_ACK, with requests
repeated when an item does not come (``retry_s``) and the transfer abandoned after ``max_retries``. The whole plan
is handed to ``accept(items)`` once complete, which returns a MAV_MISSION_RESULT (the commander may refuse it);
the stored plan only changes on acceptance, as in PX4. Download serves the stored items as received.
Only plain missions (MAV_MISSION_TYPE_MISSION) are kept; empty geofence/rally plans are accepted and reported
empty, non-empty ones are refused as unsupported.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink

MISSION = mavlink.MAV_MISSION_TYPE_MISSION


@dataclass(frozen=True)
class MissionItem:
    """One stored item, as MISSION_ITEM_INT carries it (x, y: degE7 in global frames, m*1e4 in local ones)."""

    seq: int
    frame: int
    command: int
    autocontinue: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: int
    y: int
    z: float

    @staticmethod
    def from_message(m) -> MissionItem:
        """From MISSION_ITEM_INT, or the legacy float MISSION_ITEM (lat/lon in degrees)."""
        if m.get_type() == "MISSION_ITEM":
            global_frame = m.frame in (mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                       mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT)
            scale = 1e7 if global_frame else 1e4
            x, y = _scaled_int32(m.x, scale, "x"), _scaled_int32(m.y, scale, "y")
            frame = {mavlink.MAV_FRAME_GLOBAL: mavlink.MAV_FRAME_GLOBAL_INT,
                     mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT: mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                     mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT: mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT}.get(m.frame,
                                                                                                      m.frame)
        else:
            x, y, frame = int(m.x), int(m.y), m.frame
        return MissionItem(int(m.seq), int(frame), int(m.command), int(m.autocontinue), float(m.param1),
                           float(m.param2), float(m.param3), float(m.param4), x, y, float(m.z))

    def encode(self, mav: mavlink.MAVLink, target_system: int, target_component: int, current: bool):
        return mav.mission_item_int_encode(target_system, target_component, self.seq, self.frame, self.command,
                                           int(current), self.autocontinue, self.param1, self.param2, self.param3,
                                           self.param4, self.x, self.y, self.z, MISSION)


class BadItem(ValueError):
    """An item whose field cannot be stored (``result``: the MAV_MISSION_RESULT that names it)."""

    def __init__(self, result: int, text: str) -> None:
        super().__init__(text)
        self.result = result


def _scaled_int32(v: float, scale: float, name: str) -> int:
    """A legacy MISSION_ITEM's float x/y as MISSION_ITEM_INT's int32 (degE7 or m*1e4)."""
    scaled = float(v) * scale
    if not (abs(scaled) <= 2**31 - 1):  # NaN too
        result = mavlink.MAV_MISSION_INVALID_PARAM5_X if name == "x" else mavlink.MAV_MISSION_INVALID_PARAM6_Y
        raise BadItem(result, f"MISSION_ITEM {name} = {v} does not fit MISSION_ITEM_INT")
    return round(scaled)


@dataclass
class _Upload:
    count: int
    send: Callable
    target: tuple[int, int]
    items: list
    last_request_s: float
    retries: int = 0


class MissionProtocol:
    """Mission micro-service state. ``handle(msg, send, now)`` for each mission message; ``poll(now)`` regularly.

    ``send(msg_factory)`` sends on the link the message came from: it is called with a function of a pymavlink
    codec (``lambda mav: mav.mission_ack_encode(...)``) so each link packs with its own sequence numbers.
    ``accept(items) -> int`` (a MAV_MISSION_RESULT), ``clear() -> bool`` and ``set_current(seq) -> bool`` act on
    the commander; ``current()`` gives the item being flown (-1: none).
    """

    def __init__(self, accept: Callable, clear: Callable, set_current: Callable, current: Callable,
                 retry_s: float = 0.5, max_retries: int = 5) -> None:
        self.items: list[MissionItem] = []
        self._accept, self._clear, self._set_current, self._current = accept, clear, set_current, current
        self.retry_s, self.max_retries = retry_s, max_retries
        self._upload: _Upload | None = None
        self.uploads_completed = 0
        self.uploads_failed = 0

    @staticmethod
    def _ack(send: Callable, target: tuple[int, int], result: int, mission_type: int = MISSION) -> None:
        send(lambda mav: mav.mission_ack_encode(target[0], target[1], result, mission_type))

    def _request(self, up: _Upload, now: float) -> None:
        seq = len(up.items)
        up.last_request_s = now
        up.send(lambda mav: mav.mission_request_int_encode(up.target[0], up.target[1], seq, MISSION))

    def handle(self, m, send: Callable, now: float) -> None:
        kind = m.get_type()
        target = (m.get_srcSystem(), m.get_srcComponent())
        mission_type = getattr(m, "mission_type", MISSION)
        if kind == "MISSION_COUNT":
            if mission_type != MISSION:
                ok = m.count == 0
                self._ack(send, target, mavlink.MAV_MISSION_ACCEPTED if ok else mavlink.MAV_MISSION_UNSUPPORTED,
                          mission_type)
                return
            if m.count == 0:
                ok = bool(self._clear())
                if ok:
                    self.items = []
                self._ack(send, target, mavlink.MAV_MISSION_ACCEPTED if ok else mavlink.MAV_MISSION_DENIED)
                return
            if m.count > 10000:
                self._ack(send, target, mavlink.MAV_MISSION_NO_SPACE)
                return
            self._upload = _Upload(int(m.count), send, target, [], now)
            self._request(self._upload, now)
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            up = self._upload
            if up is None or mission_type != MISSION:
                return
            if m.seq != len(up.items):
                if m.seq > len(up.items):
                    self._request(up, now)  # out of sequence: ask again for the one we need
                return
            try:
                up.items.append(MissionItem.from_message(m))
            except BadItem as e:  # the transfer ends with the reason, as PX4's does
                self._upload = None
                self.uploads_failed += 1
                self._ack(up.send, up.target, e.result)
                return
            up.retries = 0
            if len(up.items) < up.count:
                self._request(up, now)
                return
            self._upload = None
            try:
                result = int(self._accept(list(up.items)))
            except Exception:  # noqa: BLE001 - a plan the commander cannot take is an error, not a crash
                result = mavlink.MAV_MISSION_ERROR
            if result == mavlink.MAV_MISSION_ACCEPTED:
                self.items = up.items
                self.uploads_completed += 1
            else:
                self.uploads_failed += 1
            self._ack(up.send, up.target, result)
        elif kind == "MISSION_REQUEST_LIST":
            n = len(self.items) if mission_type == MISSION else 0
            send(lambda mav: mav.mission_count_encode(target[0], target[1], n, mission_type))
        elif kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            if mission_type != MISSION or not 0 <= m.seq < len(self.items):
                self._ack(send, target, mavlink.MAV_MISSION_INVALID_SEQUENCE, mission_type)
                return
            item = self.items[m.seq]
            current = item.seq == self._current()
            if kind == "MISSION_REQUEST_INT":
                send(lambda mav: item.encode(mav, target[0], target[1], current))
            else:
                send(lambda mav: _legacy_item(mav, item, target, current))
        elif kind == "MISSION_CLEAR_ALL":
            if mission_type != MISSION:
                self._ack(send, target, mavlink.MAV_MISSION_ACCEPTED, mission_type)
                return
            ok = bool(self._clear())
            if ok:
                self.items = []
            self._ack(send, target, mavlink.MAV_MISSION_ACCEPTED if ok else mavlink.MAV_MISSION_DENIED)
        elif kind == "MISSION_SET_CURRENT" and 0 <= m.seq < len(self.items):
            self._set_current(int(m.seq))
        elif kind == "MISSION_ACK" and self._upload is not None and self._upload.target == target:
            self._upload = None  # the client gave up on its upload
            self.uploads_failed += 1

    def poll(self, now: float) -> None:
        up = self._upload
        if up is None or now - up.last_request_s < self.retry_s:
            return
        up.retries += 1
        if up.retries > self.max_retries:
            self._upload = None
            self.uploads_failed += 1
            self._ack(up.send, up.target, mavlink.MAV_MISSION_OPERATION_CANCELLED)
            return
        self._request(up, now)


def _legacy_item(mav: mavlink.MAVLink, item: MissionItem, target: tuple[int, int], current: bool):
    global_frame = item.frame in (mavlink.MAV_FRAME_GLOBAL_INT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                                  mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT)
    scale = 1e7 if global_frame else 1e4
    frame = {mavlink.MAV_FRAME_GLOBAL_INT: mavlink.MAV_FRAME_GLOBAL,
             mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
             mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT: mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT}.get(item.frame, item.frame)
    return mav.mission_item_encode(target[0], target[1], item.seq, frame, item.command, int(current),
                                   item.autocontinue, item.param1, item.param2, item.param3, item.param4,
                                   item.x / scale, item.y / scale, item.z, MISSION)
