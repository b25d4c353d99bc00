"""Plain-language mission requests (cufund.missions.parse_mission): the offline grammar's phrases give the missions
written out by hand here, unsafe or malformed requests are refused with the reason, and the optional chat endpoint
is exercised against a fake OpenAI-compatible server on 127.0.0.1 (hostile replies refused)."""

from __future__ import annotations

import dataclasses
import http.server
import json
import math
import threading
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from cufund.missions import MissionRequestError, parse_mission
from cufund.missions.fleet_polygon import polygon_contains
from cufund.missions.fleet_timing import commander_trajectory
from cufund.missions.mission_request import FleetContext, Formation, GoHome, Orbit, Survey, Waypoints, Zigzag
from cufund.missions.mission_request_llm import ENV_API_KEY, ENV_BASE_URL, ENV_MODEL, LlmEndpoint
from cufund.missions.mission_request_schema import mission_from_data

FIELD = [(0.0, 0.0), (30.0, 0.0), (30.0, 20.0), (0.0, 20.0)]
FLEET = FleetContext(
    names=("uav1", "uav2", "uav3"),
    homes={"uav1": (0.0, -3.0, 0.0), "uav2": (15.0, -3.0, 0.0), "uav3": (30.0, -3.0, 0.0)},
    fields={"field": FIELD},
    geofence=[(-5.0, -5.0), (35.0, -5.0), (35.0, 25.0), (-5.0, 25.0)],
)
ONE = FleetContext(names=("uav1",), fields={"field": FIELD}, geofence=FLEET.geofence)


@pytest.fixture(autouse=True)
def _no_endpoint(monkeypatch):
    for k in (ENV_BASE_URL, ENV_MODEL, ENV_API_KEY):
        monkeypatch.delenv(k, raising=False)


def _boustrophedon(rows, altitude):
    """rows: lists of (x, y), each in ascending order; the even rows flown forward, the odd ones backward."""
    pts = []
    for i, row in enumerate(rows):
        pts += row if i % 2 == 0 else row[::-1]
    return np.array([(x, y, altitude) for x, y in pts])


@pytest.mark.parametrize(
    "text",
    [
        "Generate a zigzag path with three rows, each row containing five waypoints",
        "generate a zig-zag path with 3 rows, each row containing 5 waypoints",
    ],
)
def test_the_papers_sentence_gives_3_rows_of_5_in_boustrophedon_order(text):
    m = parse_mission(text)
    assert isinstance(m, Zigzag) and (m.rows, m.per_row) == (3, 5)
    wp = m.waypoints()
    assert list(wp) == ["uav1"]
    # the default context: home at the origin, points 2 m apart, 5 m high
    rows = [[(2.0 * j, 2.0 * i) for j in range(5)] for i in range(3)]
    np.testing.assert_array_equal(wp["uav1"], _boustrophedon(rows, 5.0))


def test_zigzag_over_the_field_at_10_m():
    m = parse_mission("zigzag over the field with 3 rows of 5 waypoints at 10 m", ONE)
    assert m.altitude == 10.0 and m.area == "field"
    # a 3 x 5 grid of the 30 m x 20 m field's cells, at their centres, rows along its long side
    rows = [[(3.0 + 6.0 * j, 20.0 / 6 * (2 * i + 1)) for j in range(5)] for i in range(3)]
    np.testing.assert_allclose(m.waypoints(ONE)["uav1"], _boustrophedon(rows, 10.0), atol=1e-9)


def test_a_zigzag_over_a_vast_polygon_is_planned_at_once():
    """Its rows come from the polygon's extent, not from a sweep at some lane spacing: a 2000 km wide area (from a
    chat endpoint, say) is refused or planned in milliseconds, not swept by two million 1 m lanes first."""
    r = 1e6
    area = [[r * math.cos(2 * math.pi * k / 40), r * math.sin(2 * math.pi * k / 40)] for k in range(40)]
    data = {"mission": "zigzag", "rows": 3, "per_row": 5, "altitude": 10, "area": area}
    t0 = time.perf_counter()
    wp = mission_from_data(data).waypoints()["uav1"]
    assert time.perf_counter() - t0 < 5.0
    assert wp.shape == (15, 3) and np.all(wp[:, 2] == 10.0)
    assert np.ptp(wp[:, :2], axis=0).max() > r  # the rows span the polygon
    assert polygon_contains(area, wp[:, :2]).all()
    with pytest.raises(MissionRequestError, match="outside the geofence"):
        mission_from_data(data, ONE)


def test_a_long_strip_is_surveyed_and_a_vast_area_refused():
    """The waypoint limit is checked on the fewest lanes a sweep needs: a 1.5 km x 4 m strip at 2 m spacing is two
    lanes along it (4 waypoints), not refused for the 1000-odd lanes a sweep across it would be."""
    strip = [(0.0, 0.0), (1500.0, 0.0), (1500.0, 4.0), (0.0, 4.0)]
    wp = mission_from_data({"mission": "survey", "area": strip, "spacing": 2.0})
    np.testing.assert_array_equal(wp.waypoints()["uav1"], [[0, 1, 5], [1500, 1, 5], [1500, 3, 5], [0, 3, 5]])
    square = [(0.0, 0.0), (2000.0, 0.0), (2000.0, 2000.0), (0.0, 2000.0)]
    with pytest.raises(MissionRequestError, match=r"too many waypoints: .* at least 4000 waypoints \(2000 lanes\)"):
        mission_from_data({"mission": "survey", "area": square, "spacing": 1.0}, FleetContext(names=("a", "b")))


def test_a_zigzag_over_a_u_shaped_area_keeps_its_waypoints_in_it():
    """A row that crosses the U's gap spreads its waypoints over its two pieces inside (1, 3 | 9, 11), none in
    the gap between the arms."""
    u_shape = [(0.0, 0.0), (12.0, 0.0), (12.0, 12.0), (8.0, 12.0), (8.0, 4.0), (4.0, 4.0), (4.0, 12.0), (0.0, 12.0)]
    m = mission_from_data({"mission": "zigzag", "rows": 3, "per_row": 4, "area": u_shape, "altitude": 3})
    rows = [[(1.5, 2.0), (4.5, 2.0), (7.5, 2.0), (10.5, 2.0)], [(1.0, 6.0), (3.0, 6.0), (9.0, 6.0), (11.0, 6.0)],
            [(1.0, 10.0), (3.0, 10.0), (9.0, 10.0), (11.0, 10.0)]]  # fmt: skip
    wp = m.waypoints()["uav1"]
    np.testing.assert_allclose(wp, _boustrophedon(rows, 3.0), atol=1e-9)
    assert polygon_contains(u_shape, wp[:, :2]).all()


def test_a_fleet_shares_the_zigzag_rows():
    wp = parse_mission("zigzag over the field with 3 rows of 5 waypoints at 10 m", FLEET).waypoints(FLEET)
    one = parse_mission("zigzag over the field with 3 rows of 5 waypoints at 10 m", ONE).waypoints(ONE)["uav1"]
    np.testing.assert_array_equal(np.concatenate([wp["uav1"], wp["uav2"], wp["uav3"]]), one)


def test_orbit():
    m = parse_mission("orbit (4, 2) at radius 3 m", ONE)
    assert isinstance(m, Orbit) and m.center == (4.0, 2.0) and m.radius == 3.0 and m.laps == 1
    wp = m.waypoints(ONE)["uav1"]
    np.testing.assert_allclose(np.hypot(wp[:, 0] - 4, wp[:, 1] - 2), 3.0)
    np.testing.assert_allclose(wp[0], wp[-1], atol=1e-12)
    np.testing.assert_allclose(wp[0], [7.0, 2.0, 5.0], atol=1e-12)  # starts east of the centre
    angles = np.unwrap(np.arctan2(wp[:, 1] - 2, wp[:, 0] - 4))
    np.testing.assert_allclose(angles[-1] - angles[0], 2 * math.pi)  # one counter-clockwise lap
    m2 = parse_mission("circle around (0, 0) with a 5 m radius twice at 6 m", ONE)
    assert (m2.radius, m2.laps, m2.altitude) == (5.0, 2, 6.0)


def test_survey_this_polygon_with_all_drones():
    area = [(0.0, 0.0), (12.0, 0.0), (12.0, 8.0), (0.0, 8.0)]
    m = parse_mission("survey this polygon with all drones", FLEET, area=area)
    assert isinstance(m, Survey) and m.vehicles == ()
    wp = m.waypoints(FLEET)
    assert set(wp) == {"uav1", "uav2", "uav3"}
    for p in wp.values():
        assert len(p) >= 2 and np.all(p[:, 2] == FLEET.default_altitude)
        assert np.all((p[:, 0] >= 0) & (p[:, 0] <= 12) & (p[:, 1] >= 0) & (p[:, 1] <= 8))
    with pytest.raises(MissionRequestError, match="no area selected"):
        parse_mission("survey this polygon with all drones", FLEET)
    named = parse_mission("survey the field at 4 m with 4 m spacing", FLEET)
    assert named.area == "field" and (named.altitude, named.spacing) == (4.0, 4.0)


def test_go_back_home():
    m = parse_mission("go back home", FLEET)
    assert isinstance(m, GoHome)
    cmds = m.commands(FLEET)
    assert {n: [c.command for c in cs] for n, cs in cmds.items()} == {n: ["rtl"] for n in FLEET.names}
    assert isinstance(parse_mission("Return to launch, uav2", FLEET), GoHome)
    assert parse_mission("RTL uav2", FLEET).vehicles == ("uav2",)


def test_waypoints_and_vehicle_names():
    m = parse_mission("fly to (1, 2, 3) then (4, 5, 3) with drone 2", FLEET)
    assert isinstance(m, Waypoints) and m.vehicles == ("uav2",)
    np.testing.assert_array_equal(m.waypoints(FLEET)["uav2"], [[1, 2, 3], [4, 5, 3]])
    cmds = m.commands(FLEET)["uav2"]
    assert [c.command for c in cmds] == ["mission_upload", "mission_start"]
    assert [i.p_W for i in cmds[0].items] == [(1.0, 2.0, 3.0), (4.0, 5.0, 3.0)]
    with pytest.raises(MissionRequestError, match="one vehicle"):
        parse_mission("fly to (1, 2, 3)", FLEET)
    assert parse_mission("fly to (1, 2, 3)", FLEET, vehicles=["uav3"]).vehicles == ("uav3",)


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("orbit (40, 2) at radius 3 m", "outside the geofence"),
        ("fly to (1, 2, 3) then (80, 2, 3) with uav1", "outside the geofence"),
        ("zigzag 3 by 5 at -2 m", "below ground"),
        ("survey the field at 0.5 m", "below the minimum altitude"),
        ("orbit (4, 2) at radius 3 m at 200 m", "above the maximum altitude"),
        ("zigzag with 100 rows of 100 waypoints", "too many waypoints"),
        ("orbit (4, 2) at radius 3 m 200 times", "between 1 and 100"),
        ("orbit (4, 2) at radius 3 m 90 times", "too many waypoints"),
        ("orbit (4, 2) at radius 3 m with uav9", "unknown vehicle"),
        ("go home, drone 7", "unknown vehicle"),
        ("zigzag with 3 rows", "waypoints per row"),
        ("zigzag with 5 waypoints", "number of rows"),
        ("orbit at radius 3 m", "centre"),
        ("orbit (4, 2)", "radius"),
        ("orbit (4, 2) at radius 0 m", "radius"),
        ("", "empty"),
    ],
)
def test_unsafe_or_malformed_requests_are_refused_with_the_reason(text, reason):
    with pytest.raises(MissionRequestError, match=reason):
        parse_mission(text, FLEET)


def test_an_unknown_field_is_refused():
    ctx = FleetContext(fields={"north": FIELD})
    with pytest.raises(MissionRequestError, match="no field of that name: the known fields are north"):
        parse_mission("survey the south field", ctx)
    assert parse_mission("survey north", ctx).area == "north"


def test_free_text_without_an_endpoint_says_so():
    with pytest.raises(MissionRequestError, match=f"none is configured.*{ENV_BASE_URL}"):
        parse_mission("take some nice pictures of the barn", FLEET)


def test_missions_are_frozen_and_their_data_round_trips():
    for text in ("zigzag over the field with 3 rows of 5 waypoints at 10 m", "orbit (4, 2) at radius 3 m",
                 "survey the field", "go back home", "fly to (1, 2, 3) with uav1"):  # fmt: skip
        m = parse_mission(text, FLEET)
        assert mission_from_data(json.loads(json.dumps(m.to_data())), FLEET) == m
        field = dataclasses.fields(m)[0].name
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(m, field, None)


# -- the chat endpoint -------------------------------------------------------------------------------------------


class _FakeChat:
    """An OpenAI-compatible /v1/chat/completions on 127.0.0.1 that answers ``content`` (or a raw body)."""

    def __init__(self):
        self.requests = []
        self.content = "{}"
        self.raw = None
        self.status = 200
        self.reason = None  # the status line's reason phrase (None: the standard one)
        self.drip_s = 0.0  # > 0: the body one byte at a time, this long apart
        owner = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_POST(self):
                body = self.rfile.read(int(self.headers["Content-Length"]))
                owner.requests.append((self.path, dict(self.headers), json.loads(body)))
                out = owner.raw if owner.raw is not None else json.dumps(
                    {"choices": [{"message": {"role": "assistant", "content": owner.content}}]}
                ).encode()  # fmt: skip
                self.send_response(owner.status, owner.reason)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(out)))
                self.end_headers()
                if not owner.drip_s:
                    self.wfile.write(out)
                    return
                try:
                    for b in out:
                        self.wfile.write(bytes([b]))
                        self.wfile.flush()
                        time.sleep(owner.drip_s)
                except OSError:
                    pass  # the client gave up

            def log_message(self, *args):
                pass

        self.server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.thread = threading.Thread(target=self.server.serve_forever, kwargs={"poll_interval": 0.02}, daemon=True)
        self.thread.start()
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/v1"

    def close(self):
        self.server.shutdown()
        self.server.server_close()
        self.thread.join(5)


@pytest.fixture
def chat(monkeypatch):
    fake = _FakeChat()
    monkeypatch.setenv(ENV_BASE_URL, fake.url)
    monkeypatch.setenv(ENV_MODEL, "test-model")
    monkeypatch.setenv(ENV_API_KEY, "sk-test")
    yield fake
    fake.close()


def test_free_text_goes_to_the_configured_endpoint_and_through_the_same_schema(chat):
    chat.content = json.dumps({"mission": "orbit", "center": [4, 2], "radius": 3, "altitude": 6, "laps": 2})
    m = parse_mission("keep circling the barn at (4, 2) please", FLEET)
    assert m == Orbit(center=(4.0, 2.0), radius=3.0, altitude=6.0, laps=2)
    path, headers, body = chat.requests[0]
    assert path == "/v1/chat/completions"
    assert headers["Authorization"] == "Bearer sk-test"
    assert body["model"] == "test-model"
    assert body["messages"][-1] == {"role": "user", "content": "keep circling the barn at (4, 2) please"}
    # a fenced JSON answer is read too; a built-in phrase never goes to the endpoint
    chat.content = "```json\n" + json.dumps({"mission": "go_home", "vehicles": ["uav1"]}) + "\n```"
    assert parse_mission("everybody, call it a day", FLEET) == GoHome(vehicles=("uav1",))
    parse_mission("go back home", FLEET)
    assert len(chat.requests) == 2


@pytest.mark.parametrize(
    ("content", "reason"),
    [
        (json.dumps({"mission": "orbit", "center": [4, 2], "radius": "three"}), "radius"),
        (json.dumps({"mission": "orbit", "center": "barn", "radius": 3}), "center"),
        (json.dumps({"mission": "orbit", "center": [4, 2], "radius": True}), "radius"),
        (json.dumps({"mission": "zigzag", "rows": 2.5, "per_row": 3}), "whole number"),
        (json.dumps({"mission": "waypoints", "points": [[0, 0, 5]] * 12000, "vehicles": ["uav1"]}), "waypoints"),
        (json.dumps({"mission": "survey", "area": [[0, 0]] * 5000}), "vertices"),
        ('{"mission": "orbit", "center": [4, NaN], "radius": 3}', "NaN"),
        ('{"mission": "orbit", "center": [4, 2], "radius": Infinity}', "Infinity"),
        ('{"mission": "orbit", "center": [4, 2], "radius": 1e999}', "out of range"),
        ('{"mission": "orbit", "center": [4, 2], "radius": 1' + "0" * 400 + "}", "finite number"),
        ('{"mission": "zigzag", "rows": 1' + "0" * 400 + ', "per_row": 2}', "whole number"),
        ('{"mission": "survey", "area": [[0, 0], [1' + "0" * 400 + ", 0], [0, 1]]}", "finite numbers"),
        (json.dumps({"mission": "orbit", "center": [4, 2], "radius": 3, "exec": "rm -rf /"}), "unknown field"),
        (json.dumps({"mission": "self_destruct"}), "mission must be one of"),
        (json.dumps({"mission": ["orbit"], "center": [4, 2], "radius": 3}), "mission must be one of"),
        (json.dumps({"mission": {"kind": "orbit"}}), "mission must be one of"),
        (json.dumps({"mission": "orbit", "center": [400, 2], "radius": 3}), "outside the geofence"),
        (json.dumps({"mission": "go_home", "vehicles": ["uav1; drop table"]}), "not a name"),
        (json.dumps(["orbit", 4, 2]), "not a JSON object"),
        ("Sure! I will orbit the barn.", "not valid JSON"),
        ('{"mission": "orbit", "center": ' + "[" * 50000 + "]" * 50000 + "}", "nested too deeply"),
        (json.dumps({"mission": None, "reason": "I cannot fly to the moon"}), "found no mission"),
    ],
)
def test_hostile_proposals_are_refused(chat, content, reason):
    chat.content = content
    with pytest.raises(MissionRequestError, match=reason):
        parse_mission("do the thing over the barn", FLEET)


def test_bad_replies_are_refused(chat):
    chat.raw = b"<html>not json</html>"
    with pytest.raises(MissionRequestError, match="not an OpenAI chat completion"):
        parse_mission("do the thing", FLEET)
    chat.raw = b'{"choices": []}'
    with pytest.raises(MissionRequestError, match="not an OpenAI chat completion"):
        parse_mission("do the thing", FLEET)
    chat.raw = b"[" * 100000 + b"]" * 100000
    with pytest.raises(MissionRequestError, match="not an OpenAI chat completion: nested too deeply"):
        parse_mission("do the thing", FLEET)
    chat.raw = b" " * (300 * 1024)
    with pytest.raises(MissionRequestError, match="over .* bytes"):
        parse_mission("do the thing", FLEET)
    chat.raw, chat.status = b"{}", 500
    with pytest.raises(MissionRequestError, match="HTTP 500"):
        parse_mission("do the thing", FLEET)
    chat.reason = "Internal Server Error " + "x" * 60000  # the whole status line is the server's to choose
    with pytest.raises(MissionRequestError, match="HTTP 500 Internal Server Error x") as refused:
        parse_mission("do the thing", FLEET)
    assert len(str(refused.value)) <= 300


def test_a_fence_around_blanks_is_refused_at_once(chat):
    """A message of a code fence and thousands of blanks is no JSON, found out in milliseconds (a backtracking
    pattern took minutes over it)."""
    chat.content = "```" + " " * 5000 + "x"
    t0 = time.monotonic()
    with pytest.raises(MissionRequestError, match="not valid JSON"):
        parse_mission("do the thing", FLEET)
    assert time.monotonic() - t0 < 5.0
    chat.content = "  ```json \n" + json.dumps({"mission": "go_home"}) + "\n```  "
    assert parse_mission("do the thing", FLEET) == GoHome()
    chat.content = "``` " + json.dumps({"mission": "go_home", "vehicles": ["uav2"]}) + "```"
    assert parse_mission("do the thing", FLEET) == GoHome(vehicles=("uav2",))


def test_a_reply_dripping_in_is_cut_off_at_the_timeout(chat):
    """Each byte within the socket timeout, the whole far beyond it: refused once timeout_s has passed."""
    chat.content = json.dumps({"mission": "go_home"})
    chat.drip_s = 0.05  # ~80 bytes: 4 s
    ep = LlmEndpoint(chat.url, "test-model", timeout_s=0.5)
    t0 = time.monotonic()
    with pytest.raises(MissionRequestError, match="took longer than 0.5 s"):
        parse_mission("do the thing", FLEET, endpoint=ep)
    assert time.monotonic() - t0 < 2.5


def test_endpoint_configuration_is_checked(monkeypatch):
    with pytest.raises(MissionRequestError, match="http"):
        LlmEndpoint("file:///etc/passwd", "m")
    with pytest.raises(MissionRequestError, match=ENV_MODEL):
        LlmEndpoint("http://127.0.0.1:9/v1", "")
    # nothing listens on the discard port: refused with the reason, no hang
    ep = LlmEndpoint("http://127.0.0.1:9/v1", "m", timeout_s=5.0)
    with pytest.raises(MissionRequestError, match="cannot be reached"):
        parse_mission("do the thing", FLEET, endpoint=ep)


def test_formation_request():
    ctx = FleetContext(
        names=("uav1", "uav2", "uav3"), homes={"uav1": (0, -3, 0), "uav2": (3, -3, 0), "uav3": (-3, -3, 0)}
    )
    m = parse_mission("fly in a wedge formation through (0, 0) and (20, 0) at 3 m, 3 m apart", ctx)
    assert isinstance(m, Formation) and (m.shape, m.spacing) == ("wedge", 3.0)
    wp = m.waypoints(ctx)
    c, s = 3.0 * math.cos(math.pi / 6), 3.0 * math.sin(math.pi / 6)  # the wedge's arms 30 degrees off the heading
    np.testing.assert_allclose(wp["uav1"], [[0, 0, 3], [20, 0, 3]], atol=1e-12)
    np.testing.assert_allclose(wp["uav2"], [[-c, s, 3], [20 - c, s, 3]], atol=1e-12)
    np.testing.assert_allclose(wp["uav3"], [[-c, -s, 3], [20 - c, -s, 3]], atol=1e-12)
    # the assembly: each waits at the start for the last to arrive (the commander's default 1 m/s legs from rest)
    holds = m.holds(ctx)
    assert min(h[0] for h in holds.values()) == 0.0 and all(np.all(h[1:] == 0) for h in holds.values())
    assert max(h[0] for h in holds.values()) > 1.0  # their flights to the start differ: the early ones wait
    # ... so that, as the commanders fly it, all leave the start at the same moment
    leave = []
    for n in ctx.names:
        tr = commander_trajectory(ctx.home(n), wp[n], None, False, holds[n])
        leave.append(tr.t[np.all(np.abs(tr.p - wp[n][0]) < 1e-9, axis=1)].max())
    assert np.ptp(leave) < 1e-9, leave
    assert parse_mission("line abreast along (0, 0) (10, 10) at 4 m", ctx).shape == "line"
    assert parse_mission("fly in a column formation through (0, 0) (10, 0)", ctx).shape == "column"
    with pytest.raises(MissionRequestError, match="at least two points"):
        parse_mission("fly in formation", ctx)


# -- robustness: any text, any JSON-like data: a mission or a MissionRequestError, nothing else ----------------------

_WORDS = ["zigzag", "orbit", "survey", "go", "home", "fly", "to", "formation", "wedge", "rows", "waypoints", "radius",
          "at", "m", "with", "all", "drones", "uav2", "drone", "field", "this", "polygon", "(4, 2)", "(1, 2, 3)", "-5",
          "1e9", "three", "twenty-five", "nan", "0", "999999", "by", "x", "apart", "spacing", "laps"]  # fmt: skip


@settings(max_examples=300, deadline=None)
@given(hs.one_of(hs.text(max_size=200), hs.lists(hs.sampled_from(_WORDS), max_size=14).map(" ".join)))
def test_any_text_gives_a_mission_or_a_reason(text):
    try:
        m = parse_mission(text, FLEET, area=[(0, 0), (10, 0), (10, 10)])
    except MissionRequestError as e:
        assert str(e)
    else:
        wp = m.waypoints(FLEET)
        assert all(np.all(np.isfinite(w)) and len(w) <= FLEET.max_waypoints for w in wp.values())


_JSON = hs.recursive(
    hs.none()
    | hs.booleans()
    | hs.integers()
    | hs.sampled_from([10**400, -(10**30)])
    | hs.floats()
    | hs.text(max_size=10),
    lambda inner: hs.lists(inner, max_size=5) | hs.dictionaries(hs.text(max_size=8), inner, max_size=5),
    max_leaves=20,
)


@settings(max_examples=300, deadline=None)
@given(
    hs.sampled_from(["zigzag", "orbit", "survey", "go_home", "waypoints", "formation", None, 3]) | _JSON,
    hs.dictionaries(
        hs.sampled_from(
            [
                "rows",
                "per_row",
                "altitude",
                "area",
                "spacing",
                "vehicles",
                "center",
                "radius",
                "laps",
                "points",
                "path",
                "shape",
                "extra",
            ]
        ),  # fmt: skip
        _JSON,
        max_size=6,
    ),
)
def test_any_data_gives_a_mission_or_a_reason(kind, fields):
    try:
        m = mission_from_data({"mission": kind, **fields}, FLEET)
    except MissionRequestError as e:
        assert str(e)
    else:
        assert mission_from_data(m.to_data(), FLEET) == m
