"""The MAVLink mission protocol (vehicle side): upload, download, clear, set current; and the glue between a
MAVLink plan and the commander's mission (:class:`CommanderPlan`).

Upload: MISSION_COUNT -> MISSION_REQUEST_INT(seq) for each item -> MISSION_ITEM_INT -> MISSION_ACK, with requests
repeated when an item does not come (``retry_s``, PX4's 250 ms). One transfer at a time, locked to the
system/component that sent MISSION_COUNT (its *partner*), as PX4's mavlink_mission does: a MISSION_COUNT,
MISSION_ITEM(_INT) or MISSION_CLEAR_ALL from anyone else meanwhile is answered MAV_MISSION_DENIED (busy) and
changes nothing; a transfer whose partner has been silent for ``timeout_s`` (PX4's
MAVLINK_MISSION_PROTOCOL_TIMEOUT_DEFAULT, 5 s) is abandoned (MAV_MISSION_OPERATION_CANCELLED to the partner).
An item whose command PX4's mission parser does not know is answered MAV_MISSION_UNSUPPORTED and ends the
transfer (:data:`SUPPORTED_COMMANDS`). The whole plan is handed to ``accept(items)`` once complete, which
returns a MAV_MISSION_RESULT (the commander may refuse it); the stored plan only changes on acceptance, as in
PX4. Download serves the stored items as received. Only plain missions (MAV_MISSION_TYPE_MISSION) are kept;
empty geofence/rally plans are accepted and reported empty, non-empty ones are refused as unsupported.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import common as mavlink

from . import frames

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
            global_frame = m.frame in (
                mavlink.MAV_FRAME_GLOBAL,
                mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT,
            )
            scale = 1e7 if global_frame else 1e4
            x, y = _scaled_int32(m.x, scale, "x"), _scaled_int32(m.y, scale, "y")
            frame = {
                mavlink.MAV_FRAME_GLOBAL: mavlink.MAV_FRAME_GLOBAL_INT,
                mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT: mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT: mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
            }.get(m.frame, m.frame)
        else:
            x, y, frame = int(m.x), int(m.y), m.frame
        return MissionItem(
            int(m.seq),
            int(frame),
            int(m.command),
            int(m.autocontinue),
            float(m.param1),
            float(m.param2),
            float(m.param3),
            float(m.param4),
            x,
            y,
            float(m.z),
        )

    def encode(self, mav: mavlink.MAVLink, target_system: int, target_component: int, current: bool):
        return mav.mission_item_int_encode(
            target_system,
            target_component,
            self.seq,
            self.frame,
            self.command,
            int(current),
            self.autocontinue,
            self.param1,
            self.param2,
            self.param3,
            self.param4,
            self.x,
            self.y,
            self.z,
            MISSION,
        )


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


SUPPORTED_COMMANDS = frozenset(
    getattr(mavlink, "MAV_CMD_" + n)
    for n in (
        "NAV_WAYPOINT",
        "NAV_LOITER_UNLIM",
        "NAV_LOITER_TIME",
        "NAV_LOITER_TURNS",
        "NAV_LAND",
        "NAV_TAKEOFF",
        "NAV_LOITER_TO_ALT",
        "NAV_VTOL_TAKEOFF",
        "NAV_VTOL_LAND",
        "NAV_DELAY",
        "NAV_RETURN_TO_LAUNCH",
        "NAV_ROI",
        "DO_JUMP",
        "DO_CHANGE_SPEED",
        "DO_SET_HOME",
        "DO_SET_SERVO",
        "DO_SET_ACTUATOR",
        "DO_LAND_START",
        "DO_TRIGGER_CONTROL",
        "DO_DIGICAM_CONTROL",
        "DO_MOUNT_CONFIGURE",
        "DO_MOUNT_CONTROL",
        "IMAGE_START_CAPTURE",
        "IMAGE_STOP_CAPTURE",
        "VIDEO_START_CAPTURE",
        "VIDEO_STOP_CAPTURE",
        "DO_CONTROL_VIDEO",
        "DO_SET_CAM_TRIGG_DIST",
        "DO_SET_CAM_TRIGG_INTERVAL",
        "SET_CAMERA_MODE",
        "SET_CAMERA_ZOOM",
        "SET_CAMERA_FOCUS",
        "DO_VTOL_TRANSITION",
        "DO_SET_ROI",
        "DO_SET_ROI_LOCATION",
        "DO_SET_ROI_WPNEXT_OFFSET",
        "DO_SET_ROI_NONE",
        "CONDITION_DELAY",
        "CONDITION_DISTANCE",
        "DO_GIMBAL_MANAGER_PITCHYAW",
        "DO_GIMBAL_MANAGER_CONFIGURE",
        "DO_WINCH",
        "DO_GRIPPER",
    )
)
"""Mission item commands PX4's parser takes (mavlink_mission.cpp, ``parse_mavlink_mission_item``: any other is
MAV_MISSION_UNSUPPORTED); cufund flies the NAV items among them and keeps the others for download."""


@dataclass
class _Upload:
    count: int
    send: Callable
    target: tuple[int, int]
    items: list
    last_request_s: float
    last_heard_s: float
    link: object = None
    """The link the partner speaks on: a transfer is locked to it as well as to the partner's ids (as PX4 locks it
    to one MAVLink instance), so two ground stations with the same default ids on two links cannot mix items."""


class MissionProtocol:
    """Mission micro-service state. ``handle(msg, send, now)`` for each mission message; ``poll(now)`` regularly.

    ``send(msg_factory)`` sends on the link the message came from: it is called with a function of a pymavlink
    codec (``lambda mav: mav.mission_ack_encode(...)``) so each link packs with its own sequence numbers.
    ``accept(items) -> int`` (a MAV_MISSION_RESULT), ``clear() -> bool`` and ``set_current(seq) -> bool`` act on
    the commander; ``current()`` gives the item being flown (-1: none).
    """

    def __init__(
        self,
        accept: Callable,
        clear: Callable,
        set_current: Callable,
        current: Callable,
        retry_s: float = 0.25,
        timeout_s: float = 5.0,
    ) -> None:
        self.items: list[MissionItem] = []
        self._accept, self._clear, self._set_current, self._current = accept, clear, set_current, current
        self.retry_s, self.timeout_s = retry_s, timeout_s
        self._upload: _Upload | None = None
        self.uploads_completed = 0
        self.uploads_failed = 0
        self.refused_busy = 0

    @property
    def partner(self) -> tuple[int, int] | None:
        """(sysid, compid) of the client uploading now (None: no transfer)."""
        return None if self._upload is None else self._upload.target

    @staticmethod
    def _ack(send: Callable, target: tuple[int, int], result: int, mission_type: int = MISSION) -> None:
        send(lambda mav: mav.mission_ack_encode(target[0], target[1], result, mission_type))

    def _request(self, up: _Upload, now: float) -> None:
        seq = len(up.items)
        up.last_request_s = now
        up.send(lambda mav: mav.mission_request_int_encode(up.target[0], up.target[1], seq, MISSION))

    def _end(self, up: _Upload, result: int) -> None:
        self._upload = None
        if result == mavlink.MAV_MISSION_ACCEPTED:
            self.uploads_completed += 1
        else:
            self.uploads_failed += 1
        self._ack(up.send, up.target, result)

    def _busy(self, target: tuple[int, int], link: object) -> bool:
        return self._upload is not None and (self._upload.target != target or self._upload.link is not link)

    def handle(self, m, send: Callable, now: float, link: object = None) -> None:
        kind = m.get_type()
        target = (m.get_srcSystem(), m.get_srcComponent())
        mission_type = getattr(m, "mission_type", MISSION)
        if (
            kind in ("MISSION_COUNT", "MISSION_CLEAR_ALL", "MISSION_ITEM_INT", "MISSION_ITEM")
            and mission_type == MISSION
            and self._busy(target, link)
        ):
            self.refused_busy += 1  # another client's transfer is under way: it stays whole
            self._ack(send, target, mavlink.MAV_MISSION_DENIED, mission_type)
            return
        if kind == "MISSION_COUNT":
            if mission_type != MISSION:
                ok = m.count == 0
                self._ack(
                    send, target, mavlink.MAV_MISSION_ACCEPTED if ok else mavlink.MAV_MISSION_UNSUPPORTED, mission_type
                )
                return
            self._upload = None  # the partner starting again
            if m.count == 0:
                self._clear_all(send, target)
                return
            if m.count > 10000:
                self._ack(send, target, mavlink.MAV_MISSION_NO_SPACE)
                return
            self._upload = _Upload(int(m.count), send, target, [], now, now, link)
            self._request(self._upload, now)
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            up = self._upload
            if up is None or mission_type != MISSION:
                return
            up.last_heard_s = now
            if m.seq != len(up.items):
                if m.seq > len(up.items):
                    self._request(up, now)  # out of sequence: ask again for the one we need
                return
            if int(m.command) not in SUPPORTED_COMMANDS:
                self._end(up, mavlink.MAV_MISSION_UNSUPPORTED)  # as PX4: the transfer ends with the reason
                return
            try:
                up.items.append(MissionItem.from_message(m))
            except BadItem as e:  # the transfer ends with the reason, as PX4's does
                self._end(up, e.result)
                return
            if len(up.items) < up.count:
                self._request(up, now)
                return
            self._upload = None
            try:
                result = int(self._accept(list(up.items)))
            except Exception:  # a plan the commander cannot take is an error, not a crash
                result = mavlink.MAV_MISSION_ERROR
            if result == mavlink.MAV_MISSION_ACCEPTED:
                self.items = up.items
            self._end(up, result)
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
            self._upload = None
            self._clear_all(send, target)
        elif kind == "MISSION_SET_CURRENT" and 0 <= m.seq < len(self.items):
            self._set_current(int(m.seq))
        elif kind == "MISSION_ACK" and self._upload is not None and self._upload.target == target:
            self._upload = None  # the client gave up on its upload
            self.uploads_failed += 1

    def _clear_all(self, send: Callable, target: tuple[int, int]) -> None:
        ok = bool(self._clear())
        if ok:
            self.items = []
        self._ack(send, target, mavlink.MAV_MISSION_ACCEPTED if ok else mavlink.MAV_MISSION_DENIED)

    def poll(self, now: float) -> None:
        up = self._upload
        if up is None:
            return
        if now - up.last_heard_s > self.timeout_s:  # the partner went silent: the vehicle is free again
            self._end(up, mavlink.MAV_MISSION_OPERATION_CANCELLED)
        elif now - up.last_request_s >= self.retry_s:
            self._request(up, now)


def _legacy_item(mav: mavlink.MAVLink, item: MissionItem, target: tuple[int, int], current: bool):
    global_frame = item.frame in (
        mavlink.MAV_FRAME_GLOBAL_INT,
        mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
    )
    scale = 1e7 if global_frame else 1e4
    frame = {
        mavlink.MAV_FRAME_GLOBAL_INT: mavlink.MAV_FRAME_GLOBAL,
        mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
        mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT: mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT,
    }.get(item.frame, item.frame)
    return mav.mission_item_encode(
        target[0],
        target[1],
        item.seq,
        frame,
        item.command,
        int(current),
        item.autocontinue,
        item.param1,
        item.param2,
        item.param3,
        item.param4,
        item.x / scale,
        item.y / scale,
        item.z,
        MISSION,
    )


_NAV_COMMANDS = (
    mavlink.MAV_CMD_NAV_WAYPOINT,
    mavlink.MAV_CMD_NAV_TAKEOFF,
    mavlink.MAV_CMD_NAV_LOITER_TIME,
    mavlink.MAV_CMD_NAV_LOITER_UNLIM,
)
_RELATIVE_FRAMES = (mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT)


class CommanderPlan:
    """A MAVLink plan as the commander's mission: its :class:`MissionProtocol` (``protocol``) accepts, clears and
    sets the current item through ``decide(cmd) -> CommandAck | None`` (the commander's answer, None when none
    came), places waypoints with ``origin`` and the vehicle's ``snapshot()``, and calls ``announce()`` when the
    current item changes (MISSION_CURRENT is due at once).

    The commander flies the NAV items; ``item_seq`` maps its item index to the MAVLink seq, ``plan_seqs`` /
    ``plan_wps`` hold the whole plan's waypoints (seqs and the commander's items), ``done`` says the plan was
    flown to its end.
    """

    def __init__(self, decide: Callable, snapshot: Callable, origin: Any, announce: Callable) -> None:
        self._decide, self._snapshot, self.origin, self._announce = decide, snapshot, origin, announce
        self.item_seq: list[int] = []
        self.plan_seqs: list[int] = []
        self.plan_wps: list[dict[str, Any]] = []
        self.done = False
        self.protocol = MissionProtocol(self.accept, self.clear, self.set_current, self.seq)

    def accept(self, items: list[MissionItem]) -> int:
        """Waypoints of a MAVLink plan -> the commander's mission (NAV items; other items are kept for download
        but not flown). Refused when a waypoint has a frame we cannot place."""
        s = self._snapshot()
        home = s.home_p_W if np.all(np.isfinite(s.home_p_W)) else s.p_W
        home_amsl = float(self.origin.enu_to_lla(home)[2])
        wps, seqs = [], []
        for it in items:
            if it.command not in _NAV_COMMANDS:
                continue
            if it.frame in (mavlink.MAV_FRAME_GLOBAL_INT, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT):
                if abs(it.x) > 90 * 10**7:
                    return mavlink.MAV_MISSION_INVALID_PARAM5_X  # latitude beyond a pole
                if abs(it.y) > 180 * 10**7:
                    return mavlink.MAV_MISSION_INVALID_PARAM6_Y
                amsl = it.z + (home_amsl if it.frame in _RELATIVE_FRAMES else 0.0)
                p = self.origin.lla_to_enu(np.array([frames.e7_to_deg(it.x), frames.e7_to_deg(it.y), amsl]))
            elif it.frame == mavlink.MAV_FRAME_LOCAL_NED:
                p = frames.ned_to_enu(np.array([it.x * 1e-4, it.y * 1e-4, it.z]))
            else:
                return mavlink.MAV_MISSION_UNSUPPORTED_FRAME
            if not np.all(np.isfinite(p)):
                return mavlink.MAV_MISSION_INVALID
            if p[2] < home[2]:  # below home: in the ground
                return mavlink.MAV_MISSION_INVALID_PARAM7
            yaw = None if not math.isfinite(it.param4) else float(frames.yaw_ned_to_enu(math.radians(it.param4)))
            hold = (
                it.param1
                if it.command in (mavlink.MAV_CMD_NAV_WAYPOINT, mavlink.MAV_CMD_NAV_LOITER_TIME)
                and math.isfinite(it.param1)
                and it.param1 > 0
                else 0.0
            )
            wps.append({"p_W": [float(c) for c in p], "yaw": yaw, "hold_s": float(hold)})
            seqs.append(it.seq)
        ack = self._decide({"command": "mission_upload", "items": wps})
        if ack is None:
            return mavlink.MAV_MISSION_ERROR
        if ack.result != "accepted":
            return mavlink.MAV_MISSION_DENIED
        self.item_seq = self.plan_seqs = seqs
        self.plan_wps = wps
        return mavlink.MAV_MISSION_ACCEPTED

    def clear(self) -> bool:
        ack = self._decide({"command": "mission_clear"})
        if ack is None:
            return False
        if ack.result == "accepted":
            self.item_seq, self.plan_seqs, self.plan_wps = [], [], []
            self.done = False
        return ack.result == "accepted"

    def set_current(self, seq: int) -> bool:
        """Makes MAVLink item ``seq`` (or the first waypoint after it) the next one flown: the commander gets the
        plan from there on (holding first and flying on if a mission is running, as PX4 jumps)."""
        i = next((k for k, q in enumerate(self.plan_seqs) if q >= seq), None)
        if i is None:
            return seq == 0 and not self.plan_seqs
        running = self._snapshot().mode == "mission"
        steps = (
            ([{"command": "hold"}] if running else [])
            + [{"command": "mission_upload", "items": self.plan_wps[i:]}]
            + ([{"command": "mission_start"}] if running else [])
        )
        for cmd in steps:
            ack = self._decide(cmd)
            if ack is None or ack.result != "accepted":
                return False
        self.item_seq = self.plan_seqs[i:]
        self.done = False
        self._announce()
        return True

    def reached_seqs(self, index: int) -> range:
        """MAVLink seqs reached with the commander's item ``index``: its NAV item and the non-NAV items up to the
        next NAV item (those before the first NAV item with item 0), as PX4 executes them on the way."""
        nav = self.item_seq
        if not 0 <= index < len(nav):
            return range(0)
        start = 0 if index == 0 and nav[0] == self.plan_seqs[0] else nav[index]
        end = nav[index + 1] if index + 1 < len(nav) else max(len(self.protocol.items), nav[index] + 1)
        return range(start, end)

    def seq(self, s: Any = None) -> int:
        """The MAVLink seq of the item being flown (of snapshot ``s``, default the latest)."""
        s = s if s is not None else self._snapshot()
        if s.mission_current < 0:  # not started: the item it would start with
            return self.item_seq[0] if self.item_seq else 0
        i = s.mission_current
        return self.item_seq[i] if 0 <= i < len(self.item_seq) else max(i, 0)
