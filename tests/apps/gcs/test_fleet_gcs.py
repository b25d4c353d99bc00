"""``cufund gcs fleet_square``: the fleet's station over HTTP, as its page drives it (a subprocess, killed in
teardown): per-vehicle and all-vehicle commands each answered by its own vehicle, and plain-language missions that
must be previewed before they can be flown, refusals carrying the reason."""

from __future__ import annotations

import json
import urllib.error
import urllib.request

import numpy as np
import pytest

from cufund.apps.gcs import GcsProcess
from cufund.apps.gcs.fleet_server import FLEET_COLOURS
from cufund.apps.gcs.process import wait_for

pytest.importorskip("cufund.missions.mission_request")  # parse_mission (the plain-language grammar)

PAPER = "Generate a zigzag path with three rows, each row containing five waypoints"


@pytest.fixture(scope="module")
def gcs():
    with GcsProcess("fleet_square", "--speed", "5", "--set", "planner.auto_disarm_s=0") as g:
        yield g


def http(gcs, path, body=None, headers=None, token=True):
    url = gcs.base + path + (f"?token={gcs.token}" if token else "")
    data = None if body is None else (body if isinstance(body, bytes) else json.dumps(body).encode())
    req = urllib.request.Request(url, data=data, headers=headers or {})
    try:
        with urllib.request.urlopen(req, timeout=15) as r:
            return r.status, json.loads(r.read() or b"null")
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"null")


def state(gcs):
    return http(gcs, "/api/state")[1]


def test_the_fleet_is_listed_in_its_colours(gcs):
    code, s = http(gcs, "/api/state")
    assert code == 200 and s["names"] == ["uav1", "uav2", "uav3"]
    assert [s["colours"][n] for n in s["names"]] == list(FLEET_COLOURS[:3])
    assert wait_for(lambda: all(state(gcs)["vehicles"][n].get("p_W") for n in ("uav1", "uav2", "uav3")), 10)
    homes = [state(gcs)["vehicles"][n]["p_W"][:2] for n in ("uav1", "uav2", "uav3")]
    assert np.allclose(homes, [[0, 0], [3, 0], [6, 0]], atol=0.05)  # fleet_square's start poses
    assert "truth_p_W" not in s["vehicles"]["uav1"]  # the flight state only


def test_the_guard_of_the_single_station(gcs):
    assert http(gcs, "/api/state", token=False)[0] == 403
    assert http(gcs, "/api/state", headers={"Host": "rebound.example:80"})[0] == 403  # DNS rebinding
    assert http(gcs, "/", headers={"Host": "rebound.example:80"})[0] == 403
    code, _ = http(gcs, "/api/command", {"command": {"command": "arm"}}, headers={"Origin": "http://evil.example"})
    assert code == 403
    assert http(gcs, "/api/command", b"{not json")[0] == 400
    code, body = http(gcs, "/api/command", {"command": {"command": "arm"}, "vehicles": ["uav9"]})
    assert code == 400 and "unknown vehicle uav9" in body["message"]


def test_one_vehicle_then_all(gcs):
    code, r = http(gcs, "/api/command", {"command": {"command": "arm"}, "vehicles": ["uav2"]})
    assert code == 200 and list(r["acks"]) == ["uav2"] and r["acks"]["uav2"]["result"] == "accepted"
    v = state(gcs)["vehicles"]
    assert v["uav2"]["armed"] and not v["uav1"]["armed"] and not v["uav3"]["armed"]
    code, r = http(gcs, "/api/command", {"command": {"command": "takeoff", "altitude": 1.0}, "vehicles": "all"})
    assert set(r["acks"]) == {"uav1", "uav2", "uav3"}
    assert r["acks"]["uav2"]["result"] == "accepted"
    assert r["acks"]["uav1"]["result"] == "denied" and "arm" in r["acks"]["uav1"]["message"]  # its own answer
    assert wait_for(lambda: state(gcs)["vehicles"]["uav2"]["p_W"][2] > 0.8, 30)
    http(gcs, "/api/command", {"command": {"command": "land"}, "vehicles": ["uav2"]})


def test_a_request_is_previewed_then_flown(gcs):
    code, r = http(gcs, "/api/mission/fly", {"id": 1})
    assert code == 200 and not r["ok"] and "preview" in r["reason"]
    code, p = http(gcs, "/api/mission/preview", {"text": PAPER, "vehicles": ["uav3"]})
    assert code == 200 and p["ok"], p
    wp = np.array(p["waypoints"]["uav3"])
    assert list(p["waypoints"]) == ["uav3"] and wp.shape == (15, 3)
    rows = wp[:, 1].reshape(3, 5)  # three rows of five, each at one y, x alternating direction (boustrophedon)
    assert np.allclose(rows, rows[:, :1]) and len(set(np.round(rows[:, 0], 6))) == 3
    dx = np.diff(wp[:, 0].reshape(3, 5), axis=1)
    assert np.all(dx[0] > 0) == np.all(dx[1] < 0) == np.all(dx[2] > 0)
    assert np.allclose(wp[:, 2], wp[0, 2]) and wp[0, 2] >= 1.0
    assert state(gcs)["preview"]["id"] == p["id"]
    code, r = http(gcs, "/api/mission/fly", {"id": p["id"] + 7})
    assert not r["ok"] and "not the one on the map" in r["reason"]
    code, r = http(gcs, "/api/mission/fly", {"id": p["id"]})
    assert r["ok"], r
    assert [a["command"] for a in r["acks"]["uav3"]] == ["arm", "mission_upload", "mission_start"]
    assert wait_for(lambda: state(gcs)["vehicles"]["uav3"]["mission"]["count"] == 15, 10)
    assert wait_for(lambda: state(gcs)["vehicles"]["uav3"]["p_W"][2] > 1.0, 30)
    code, r = http(gcs, "/api/mission/fly", {"id": p["id"]})
    assert not r["ok"]  # flown once: a new preview for the next
    http(gcs, "/api/command", {"command": {"command": "rtl"}, "vehicles": ["uav3"]})


@pytest.mark.parametrize(
    "text, reason",
    [
        ("zigzag with 3 rows of 5 waypoints at 0 m", "below"),
        ("zigzag over the field with 3 rows of 5 waypoints at 10 m", "no field of that name"),
        ("", "type a request"),
        ("please dance a little", "endpoint"),
    ],
)
def test_refusals_say_why(gcs, text, reason):
    code, r = http(gcs, "/api/mission/preview", {"text": text})
    assert code == 200 and not r["ok"] and reason in r["reason"], r
    assert state(gcs)["preview"] is None or state(gcs)["preview"]["text"] != text


def test_the_map_gets_the_scenarios_field_and_geofence():
    from cufund.apps.gcs.fleet_server import _areas
    from cufund.scenarios.fleet import build_fleet
    from cufund.scenarios.schema import load_scenario

    areas = _areas(build_fleet(load_scenario("fleet_survey")))
    ((name, field),) = areas["fields"].items()  # the 30 m x 20 m field
    xs, ys = zip(*field, strict=True)
    assert (max(xs) - min(xs), max(ys) - min(ys)) == (30.0, 20.0)
    assert areas["geofence"] is not None and len(areas["geofence"]) >= 3
    assert _areas(build_fleet(load_scenario("fleet_square"))) == {"fields": {}, "geofence": None}


def test_a_fleet_with_its_own_mission_waits_for_start():
    with GcsProcess("fleet_survey", "--speed", "5") as g:
        s = state(g)
        assert s["held"] and s["t"] == pytest.approx(0.01, abs=1e-6)
        assert all(s["vehicles"][n].get("p_W") for n in s["names"])  # on their pads, seen
        assert state(g)["t"] == s["t"]  # nothing flies before Start
        code, r = http(g, "/api/command", {"command": {"command": "start"}})
        assert code == 200 and r["acks"]["fleet"]["result"] == "accepted"
        assert wait_for(lambda: state(g)["t"] > 1.0, 10)
        assert not state(g)["held"]
        code, r = http(g, "/api/command", {"command": {"command": "start"}})
        assert r["acks"]["fleet"]["result"] == "denied" and "started" in r["acks"]["fleet"]["message"]
    with GcsProcess("fleet_survey", "--speed", "5", "--autostart") as g:
        assert not state(g)["held"] and wait_for(lambda: state(g)["t"] > 1.0, 10)


def test_the_station_answers_while_a_chat_endpoint_thinks(monkeypatch):
    """Free text goes to the chat endpoint (up to its 30 s timeout): meanwhile the station still shows the fleet and
    takes commands (an operator's 'land all' must not wait for a language model)."""
    import threading
    import time
    from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

    asked, answer = threading.Event(), threading.Event()

    class SlowChat(BaseHTTPRequestHandler):
        def do_POST(self) -> None:
            self.rfile.read(int(self.headers.get("Content-Length", 0)))
            asked.set()
            answer.wait(8.0)
            self.send_response(503)
            self.end_headers()

        def log_message(self, *args: object) -> None:
            pass

    chat = ThreadingHTTPServer(("127.0.0.1", 0), SlowChat)
    threading.Thread(target=chat.serve_forever, daemon=True).start()
    monkeypatch.setenv("CUFUND_LLM_BASE_URL", f"http://127.0.0.1:{chat.server_address[1]}/v1")
    monkeypatch.setenv("CUFUND_LLM_MODEL", "slow")
    try:
        with GcsProcess("fleet_square", "--speed", "5") as g:
            out: dict[str, object] = {}
            ask = threading.Thread(
                target=lambda: out.update(r=http(g, "/api/mission/preview", {"text": "please dance a little"}))
            )
            ask.start()
            assert asked.wait(15.0), "the request did not reach the chat endpoint"
            t0 = time.monotonic()
            code, s = http(g, "/api/state")
            code2, r = http(g, "/api/command", {"command": {"command": "sim_pause"}})
            waited = time.monotonic() - t0
            answer.set()
            ask.join(20.0)
            assert code == code2 == 200 and s["names"] == ["uav1", "uav2", "uav3"] and waited < 2.0, waited
            assert r["acks"]["fleet"]["result"] == "accepted"
            code, p = out["r"]  # type: ignore[misc]
            assert code == 200 and not p["ok"] and "HTTP 503" in p["reason"], p
    finally:
        answer.set()
        chat.shutdown()
        chat.server_close()


def test_the_station_takes_overrides_as_the_command_line_does():
    """``FleetGcsServer(name, overrides)`` gives fleet_square its commanders before the overrides, as
    ``cufund gcs fleet_square --set planner.auto_disarm_s=0`` does (the overrides reached the waypoints planner)."""
    from cufund.apps.gcs.fleet_server import FleetGcsServer

    g = FleetGcsServer("fleet_square", ("planner.auto_disarm_s=0",))
    try:
        assert [v.commander.params.auto_disarm_s for v in g.live.vehicles.values()] == [0.0, 0.0, 0.0]
    finally:
        g.stop()
    with pytest.raises(ValueError, match="not a fleet"):
        FleetGcsServer("vehicle")
