"""Fuzz: the MAVLink vehicle endpoint's protocol state under two ground stations interleaving the mission,
parameter and command protocols at random (hypothesis stateful testing, pymavlink clients on 127.0.0.1).

Invariants after every step: the endpoint answers (a REQUEST_MESSAGE is acked), a stored mission comes whole
from one upload of one client (every item a client sends carries its client and upload number in param3 and
param2, and item k sits at seq k), and every parameter stays inside its bounds. One live vehicle
serves every example (starting one costs seconds); what an example leaves behind is state the next one starts
from, which is itself an interleaving. Small by default; ``make fuzz`` runs it long (CUFUND_FUZZ_EXAMPLES)."""

from __future__ import annotations

import math

import pytest
from fuzz_support import CAMPAIGN, EXAMPLES, FAILURES, STATS, floats_any
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from hypothesis.stateful import RuleBasedStateMachine, invariant, rule, run_state_machine_as_test
from pymavlink.dialects.v20 import common as M

from mavlink_support import OPEN_FIELD, vehicle

AREA = "mavlink_state"
BASE = {0: 10.0, 1: 20.0}  # the height of client c's item k: BASE[c] + k [m]
PARAMS = [
    "MIS_TAKEOFF_ALT",
    "MC_ROLLRATE_P",
    "MPC_XY_P",
    "MPC_TILTMAX_AIR",
    "NAV_ACC_RAD",
    "COM_DL_LOSS_T",
    "MPC_THR_MAX",
    "GEO_K_X",
    "NO_SUCH_PARAM",
]
COMMANDS = [
    M.MAV_CMD_COMPONENT_ARM_DISARM,
    M.MAV_CMD_NAV_TAKEOFF,
    M.MAV_CMD_NAV_LAND,
    M.MAV_CMD_NAV_RETURN_TO_LAUNCH,
    M.MAV_CMD_DO_SET_MODE,
    M.MAV_CMD_MISSION_START,
    M.MAV_CMD_DO_SET_MISSION_CURRENT,
    M.MAV_CMD_SET_MESSAGE_INTERVAL,
    M.MAV_CMD_REQUEST_MESSAGE,
    M.MAV_CMD_DO_PAUSE_CONTINUE,
    12345,
]
ITEM_COMMANDS = [M.MAV_CMD_NAV_WAYPOINT, M.MAV_CMD_NAV_LOITER_TIME, M.MAV_CMD_DO_CHANGE_SPEED, 12345, 0]
STEPS = 40 if CAMPAIGN else 20
SCALE = 8  # examples per fuzz example of the suite: a step is a few milliseconds of loopback round trips


def f32(x: float) -> float:
    """``x`` as MAVLink's float32 carries it (beyond its range: infinite)."""
    return x if not math.isfinite(x) or abs(x) < 3.4e38 else math.copysign(math.inf, x)


@pytest.fixture(scope="module")
def live_vehicle():
    with vehicle(links=2, scenario=OPEN_FIELD) as (live, ep, gcss):
        gcss[1].mav.srcSystem = 254  # a second ground station
        yield live, ep, gcss


class MavlinkState(RuleBasedStateMachine):
    """Two clients (0 and 1), each with an upload it may be in the middle of."""

    shared: tuple = ()
    upload = {0: 0, 1: 0}
    """Each client's upload number (param2 of its items), kept across examples as the vehicle keeps its state."""

    def __init__(self) -> None:
        super().__init__()
        self.live, self.ep, self.gcs = self.shared
        self.plan = {0: 0, 1: 0}  # the count each client announced last
        self.cursor = {0: 0, 1: 0}  # its next item
        for g in self.gcs:  # an upload the last example left open ends: examples replay alike when shrunk
            g.mav.mission_ack_send(1, 1, M.MAV_MISSION_OPERATION_CANCELLED, 0)
            g.drain()

    def _step(self) -> None:
        STATS[AREA]["ok"] += 1

    @rule(c=st.integers(0, 1), n=st.integers(0, 4))
    def count(self, c, n):
        self.gcs[c].mav.mission_count_send(1, 1, n, 0)
        self.plan[c], self.cursor[c] = n, 0
        self.upload[c] += 1
        self._step()

    @rule(c=st.integers(0, 1), steps=st.integers(1, 4))
    def next_items(self, c, steps):
        """The client's own items, in order (whatever the vehicle asks for)."""
        g = self.gcs[c]
        for _ in range(steps):
            k = self.cursor[c]
            if k >= self.plan[c]:
                break
            g.mav.mission_item_int_send(
                1,
                1,
                k,
                M.MAV_FRAME_LOCAL_NED,
                M.MAV_CMD_NAV_WAYPOINT,
                0,
                1,
                0,
                self.upload[c],
                c + 1,
                math.nan,
                0,
                0,
                -(BASE[c] + k),
                0,
            )
            self.cursor[c] = k + 1
        self._step()

    @rule(first=st.integers(0, 1), n=st.integers(1, 4), k=st.integers(0, 4), m=st.integers(0, 4), j=st.integers(0, 4))
    def race(self, first, n, k, m, j):
        """Two uploads racing: one client announces n items and sends k, the other announces m and sends j,
        then the first sends the rest of its own."""
        other = 1 - first
        self.count(first, n)
        self.next_items(first, k)
        self.count(other, m)
        self.next_items(other, j)
        self.next_items(first, n)

    @rule(
        c=st.integers(0, 1),
        seq=st.integers(0, 5),
        command=st.sampled_from(ITEM_COMMANDS),
        frame=st.sampled_from([M.MAV_FRAME_LOCAL_NED, M.MAV_FRAME_GLOBAL_INT, M.MAV_FRAME_MISSION, 99]),
        p1=floats_any(),
        z=floats_any(),
    )
    def stray_item(self, c, seq, command, frame, p1, z):
        """An item out of turn: any seq, command, frame, values (an accepted one must still carry its seq)."""
        self.gcs[c].mav.mission_item_int_send(
            1, 1, seq, frame, command, 0, 1, f32(p1), self.upload[c], c + 1, math.nan, 0, 0, f32(z), 0
        )
        self._step()

    @rule(c=st.integers(0, 1), kind=st.sampled_from(["clear", "cancel", "list", "request"]), seq=st.integers(0, 5))
    def other_mission_message(self, c, kind, seq):
        g = self.gcs[c]
        if kind == "clear":
            g.mav.mission_clear_all_send(1, 1, 0)
        elif kind == "cancel":
            g.mav.mission_ack_send(1, 1, M.MAV_MISSION_OPERATION_CANCELLED, 0)
        elif kind == "list":
            g.mav.mission_request_list_send(1, 1, 0)
        else:
            g.mav.mission_request_int_send(1, 1, seq, 0)
        self._step()

    @rule(c=st.integers(0, 1), name=st.sampled_from(PARAMS), value=floats_any())
    def param_set(self, c, name, value):
        self.gcs[c].mav.param_set_send(1, 1, name.encode(), f32(value), M.MAV_PARAM_TYPE_REAL32)
        self._step()

    @rule(c=st.integers(0, 1), index=st.integers(-1, 60))
    def param_read(self, c, index):
        g = self.gcs[c]
        if index == 60:
            g.mav.param_request_list_send(1, 1)
        else:
            g.mav.param_request_read_send(1, 1, b"MPC_XY_P" if index < 0 else b"", index)
        self._step()

    @rule(c=st.integers(0, 1), command=st.sampled_from(COMMANDS), p=st.lists(floats_any(), min_size=7, max_size=7))
    def command(self, c, command, p):
        if command == M.MAV_CMD_COMPONENT_ARM_DISARM and p[1] == 21196.0:
            p[1] = 0.0  # no forced disarm in flight: a falling vehicle ends the shared run
        self.gcs[c].mav.command_long_send(1, 1, command, 0, *(f32(x) for x in p))
        self._step()

    @invariant()
    def responsive_whole_and_in_bounds(self):
        from cufund.apps.mavlink.param_protocol import PX4_BOUNDS

        g = self.gcs[0]
        try:
            g.mav.command_long_send(
                1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, M.MAVLINK_MSG_ID_AUTOPILOT_VERSION, 0, 0, 0, 0, 0, 0
            )
            g.recv("COMMAND_ACK", 10.0, cond=lambda m: m.command == M.MAV_CMD_REQUEST_MESSAGE)
        except AssertionError:
            FAILURES.append((AREA, "hang", "REQUEST_MESSAGE after the steps", "no COMMAND_ACK within 10 s"))
            STATS[AREA]["hang"] += 1
            raise
        items = list(self.ep.missions.items)
        origins = {(it.param3, it.param2) for it in items}  # (client, upload)
        assert len(origins) <= 1 and [it.seq for it in items] == list(range(len(items))), (
            f"stored mission mixes uploads: {[(it.seq, it.param3, it.param2) for it in items]}"
        )
        ack = self.live.submit({"command": "get_params"}).result(timeout=10)
        for name, value in ack.data.items():
            lo, hi = PX4_BOUNDS.get(name, (-math.inf, math.inf))
            if isinstance(value, (int, float)):
                assert lo <= value <= hi, f"{name} = {value} outside [{lo}, {hi}]"


def test_two_clients_interleaving_mission_parameter_and_command_protocols(live_vehicle):
    MavlinkState.shared = live_vehicle
    run_state_machine_as_test(
        MavlinkState,
        settings=settings(
            max_examples=EXAMPLES * SCALE,
            stateful_step_count=STEPS,
            deadline=None,
            database=None,
            derandomize=EXAMPLES <= 50,
            suppress_health_check=list(HealthCheck),
        ),
    )
