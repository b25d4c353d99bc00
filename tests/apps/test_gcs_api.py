"""The web ground station's HTTP and websocket API, with real clients (urllib, websocket-client) against a
`cufund gcs` subprocess: the token guards everything, commands reach the commander, tabs stay in sync and catch
up, malformed messages get an error while the simulation goes on."""

import json
import math
import socket
import urllib.error
import urllib.request

import numpy as np
import pytest

from cufund.apps.gcs import GcsProcess, parse_speed
from cufund.apps.gcs.mission_preview import preview_mission
from cufund.apps.gcs.process import wait_for
from cufund.apps.gcs.server import IN_FLIGHT
from cufund.planning.mission_spec import Region
from gcs_support import receive

websocket = pytest.importorskip("websocket")  # websocket-client, installed with selenium (test extras)


@pytest.fixture(scope="module")
def gcs():
    with GcsProcess("vehicle", "--speed", "inf", "--set", "planner.auto_disarm_s=0") as g:
        yield g


def http(gcs, path, body=None, headers=None, token=True):
    url = gcs.base + path + (f"?token={gcs.token}" if token else "")
    req = urllib.request.Request(
        url,
        data=None if body is None else (body if isinstance(body, bytes) else json.dumps(body).encode()),
        headers=headers or {},
    )
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()


def ws_connect(gcs, token=True):
    url = gcs.base.replace("http://", "ws://") + "/ws" + (f"?token={gcs.token}" if token else "")
    return websocket.create_connection(url, timeout=10, origin=gcs.base)


def test_first_line_and_token_everywhere(gcs):
    assert gcs.first_line.startswith("GCS: http://127.0.0.1:")
    assert len(gcs.token) >= 24
    for path in ("/", "/api/state"):
        assert http(gcs, path, token=False)[0] == 403
    assert http(gcs, "/api/command", {"command": "arm"}, token=False)[0] == 403
    assert (
        http(gcs, "/api/command", {"command": "arm"}, token=False, headers={"Authorization": "Bearer nope"})[0] == 403
    )
    with pytest.raises(websocket.WebSocketBadStatusException) as e:
        ws_connect(gcs, token=False)
    assert e.value.status_code == 403
    status, body = http(gcs, "/api/state", token=False, headers={"Authorization": f"Bearer {gcs.token}"})
    assert status == 200 and json.loads(body)["mode"] in ("idle", "hold", "takeoff", "goto", "mission", "land")
    assert http(gcs, "/meshcat/main.min.js", token=False)[0] == 200  # the viewer itself is public code


def test_malformed_commands_are_400_with_the_reason(gcs):
    status, body = http(gcs, "/api/command", b"{not json")
    assert status == 400
    status, body = http(gcs, "/api/command", {"command": "fly"})
    assert status == 400 and "fly" in json.loads(body)["message"]
    status, body = http(gcs, "/api/command", {"command": "goto", "p_W": [1, 2]})
    assert status == 400 and "p_W" in json.loads(body)["message"]
    status, body = http(gcs, "/api/command", {"command": "sim_speed", "speed": 50})
    assert status == 400 and "speed" in json.loads(body)["message"]


def test_malformed_ws_messages_get_errors_while_the_sim_runs(gcs):
    ws = ws_connect(gcs)
    try:
        t0 = receive(ws, "telemetry")["t"]
        for bad in (
            "not json",
            json.dumps([1, 2]),
            json.dumps({"type": "launch_missiles"}),
            json.dumps({"no": "type"}),
        ):
            ws.send(bad)
            assert receive(ws, "error")["message"]
        ws.send_binary(b"\x00\x01")
        assert "binary" in receive(ws, "error")["message"]
        ws.send(json.dumps({"type": "command", "id": 7, "command": {"command": "takeoff", "altitude": "high"}}))
        ack = receive(ws, "ack", pred=lambda m: m["id"] == 7)
        assert ack["result"] == "failed" and "altitude" in ack["message"]
        assert receive(ws, "telemetry", pred=lambda m: m["t"] > t0 + 0.5)  # the simulation went on
    finally:
        ws.close()


def test_commands_sync_tabs_and_a_new_tab_catches_up(gcs):
    a, b = ws_connect(gcs), ws_connect(gcs)
    try:
        receive(a, "hello"), receive(b, "hello")
        a.send(json.dumps({"type": "command", "id": 1, "command": {"command": "arm"}}))
        assert receive(a, "ack", pred=lambda m: m["id"] == 1)["result"] == "accepted"
        # the other tab hears of it (event log) and sees the state change (telemetry)
        assert receive(b, "events", pred=lambda m: any("arm: accepted" in e["message"] for e in m["events"]))
        assert receive(b, "telemetry", pred=lambda m: m["armed"])
        status, body = http(gcs, "/api/command", {"command": "takeoff", "altitude": 1.2})
        assert status == 200 and json.loads(body)["result"] == "accepted"
        tel = receive(b, "telemetry", timeout=20, pred=lambda m: m["p_W"][2] > 1.1 and m["mode"] == "hold")
        assert abs(tel["p_W"][2] - 1.2) < 0.1
    finally:
        a.close()
        b.close()
    # a tab that (re)connects gets the flown path, the event log and the plots' history
    c = ws_connect(gcs)
    try:
        hello = receive(c, "hello")
        path = np.array(hello["path"])
        assert path[:, 2].max() > 1.1 and path[:, 2].min() < 0.05
        messages = [e["message"] for e in hello["events"]]
        assert "armed" in messages and any(m.startswith("mode takeoff") for m in messages)
        # (at --speed inf the history's length is the wall-clock telemetry ticks the flight took, not a fixed count)
        hist_t = [h["t"] for h in hello["history"]]
        assert len(hist_t) > 2 and hist_t == sorted(hist_t) and hist_t[-1] - hist_t[0] > 1.0, hist_t
        assert hello["scene"]["meshes"]
    finally:
        c.close()


def test_server_survives_a_dead_tab(gcs):
    ws = ws_connect(gcs)
    ws.sock.shutdown(socket.SHUT_RDWR)  # vanishes without a close handshake
    ws.sock.close()
    s1 = json.loads(http(gcs, "/api/state")[1])["t"]
    assert wait_for(lambda: json.loads(http(gcs, "/api/state")[1])["t"] > s1 + 0.5, 10)
    assert gcs.alive()


def test_mission_preview_is_the_shortest_accepted_order(gcs):
    regions = [
        {"name": "a", "centre_W": [2.0, 0.0, 1.5], "radius": 0.3},
        {"name": "b", "centre_W": [-2.0, 0.0, 1.5], "radius": 0.3},
        {"name": "c", "centre_W": [0.0, 3.0, 1.5], "radius": 0.3},
    ]
    start = np.array([-1.5, 0.0, 1.5])
    plan = preview_mission({"formula": "F(a) & F(b) & G(!c)", "regions": regions}, [], start)
    # visiting b first (0.5 m away) then a (4 m) beats a then b (3.5 + 4 m): checked by hand, not by the planner
    assert plan["regions"] == ["b", "a"]
    assert plan["length"] == pytest.approx(0.5 + 4.0)
    # the world's regions are declared too; an unknown one is named
    gate = Region("gate1", (1.0, 1.0, 1.0), radius=0.2)
    assert preview_mission({"formula": "F(gate1)"}, [gate], start)["regions"] == ["gate1"]
    with pytest.raises(ValueError, match="zzz"):
        preview_mission({"formula": "F(zzz)", "regions": regions}, [], start)
    with pytest.raises(ValueError, match="formula"):
        preview_mission({"formula": ""}, [], start)
    # through the API: accepted, and every tab is shown the plan as the planned path
    status, body = http(
        gcs, "/api/command", {"command": "mission_preview", "formula": "F(a & F(c))", "regions": regions}
    )
    ack = json.loads(body)
    assert status == 200 and ack["result"] == "accepted" and ack["data"]["regions"] == ["a", "c"]


def test_parse_speed():
    assert parse_speed("inf") == math.inf and parse_speed("2.5") == 2.5
    for bad in ("0", "11", "nan", "fast-ish", None, "-inf"):
        with pytest.raises(ValueError, match="speed"):
            parse_speed(bad)


def test_a_non_loopback_host_warns():
    with GcsProcess("vehicle", "--host", "127.0.0.2") as g:
        assert g.first_line.startswith("GCS: http://127.0.0.2:")
        err = g.stop()
    assert "WARNING" in err and "127.0.0.2" in err


def test_foxglove_server_serves_the_same_telemetry():
    """A Foxglove WebSocket client (the protocol by hand: advertise, subscribe, binary message data)."""
    import struct

    with GcsProcess("vehicle", "--speed", "inf", "--foxglove", "--foxglove-port", "0") as g:
        line = g.proc.stdout.readline()
        assert line.startswith("Foxglove: ws://127.0.0.1:")
        ws = websocket.create_connection(line.split()[1], timeout=10, subprotocols=["foxglove.sdk.v1"])
        try:
            channels = {}
            while "/vehicle/telemetry" not in channels:
                m = json.loads(ws.recv())
                if m["op"] == "advertise":
                    channels.update({c["topic"]: c for c in m["channels"]})
            assert {"/vehicle/pose", "/sensors/lidar", "/vehicle/events"} <= set(channels)
            assert channels["/vehicle/pose"]["schemaName"] == "foxglove.PoseInFrame"
            ws.send(
                json.dumps(
                    {"op": "subscribe", "subscriptions": [{"id": 3, "channelId": channels["/vehicle/telemetry"]["id"]}]}
                )
            )
            ts = []
            while len(ts) < 5:
                raw = ws.recv()
                if isinstance(raw, bytes) and raw[0] == 1:  # message data: op, subscription id, log time, payload
                    (sub,) = struct.unpack_from("<I", raw, 1)
                    assert sub == 3
                    tel = json.loads(raw[13:])
                    ts.append(tel["t"])
                    assert len(tel["p_W"]) == 3
            assert ts == sorted(ts) and ts[-1] > ts[0]
        finally:
            ws.close()


def test_lidar_and_esdf_layers_show_the_world():
    """With the cloud layer on, a tab gets binary frames: float32 [t, n, xyz...] in the world frame: the measured
    points (2 cm range noise) placed with the vehicle's reported pose, on the world's surfaces within that noise; the ESDF slice (at 1 m while the vehicle stands on its pad) matches the distance to the
    world's triangles within the map's resolution. Reference: Open3D's distance queries on the world's meshes."""
    import base64

    from cufund.worlds import builtin

    o3d = pytest.importorskip("open3d")
    world = builtin.load("imav2025_tunnel")
    lo, hi = world.bounds()
    scene = o3d.t.geometry.RaycastingScene()
    for obj in world.objects:
        scene.add_triangles(
            o3d.core.Tensor(obj.vertices.astype(np.float32)), o3d.core.Tensor(obj.triangles.astype(np.uint32))
        )
    with GcsProcess(
        "vehicle",
        "--speed",
        "inf",
        "--set",
        "sensors.lidar.kind=mid360",
        "--set",
        "sensors.lidar.T_BL.p=[0,0,0.08]",
        "--set",
        "mapper.kind=esdf",
        "--set",
        "mapper.resolution=0.1",
        "--set",
        "mapper.size=[6,6,3]",
        "--set",
        "mapper.origin_W=[-5,-3,-0.5]",
        "--set",
        "mapper.max_range=10",
    ) as g:
        ws = ws_connect(g)
        try:
            receive(ws, "hello")
            ws.send(json.dumps({"type": "layers", "cloud": True}))
            ws.settimeout(30)
            frames, slices = [], []
            while len(frames) < 2 or len(slices) < 3:
                raw = ws.recv()
                if isinstance(raw, bytes):
                    frames.append(np.frombuffer(raw, dtype="<f4"))
                elif json.loads(raw)["type"] == "esdf":
                    slices.append(json.loads(raw))
        finally:
            ws.close()
    for f in frames:
        n = int(f[1])
        pts = f[2:].reshape(-1, 3)
        assert 1000 < n == len(pts) <= 8000
        assert np.all(pts >= lo - 0.15) and np.all(pts <= hi + 0.15)
        dist = scene.compute_distance(o3d.core.Tensor(pts)).numpy()  # to the world's triangles
        assert np.median(dist) < 0.02 and np.percentile(dist, 99) < 0.08  # the measured points, not the true hits
    assert frames[1][0] > frames[0][0]  # successive frames, newer stamps
    m = slices[-1]
    n = m["n"]
    assert m["z"] == 1.0 and m["x"] == [-5.0, 1.0] and m["y"] == [-3.0, 3.0]
    d = np.frombuffer(base64.b64decode(m["d"]), dtype="<f4").reshape(n, n)
    X, Y = np.meshgrid(np.linspace(*m["x"], n), np.linspace(*m["y"], n), indexing="xy")
    q = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, m["z"])]).astype(np.float32)
    truth = scene.compute_distance(o3d.core.Tensor(q)).numpy().reshape(n, n)
    assert (truth < 1.0).sum() > 500  # the slice crosses walls and frames
    assert np.abs(d - truth).max() < 0.15  # resolution 0.1 m


def test_a_tab_that_acknowledges_gets_no_more_than_it_has_read(gcs):
    """Flow control: once a tab says what it has read ({"type": "seen"}), only a few telemetry messages are
    unread (IN_FLIGHT); acknowledging releases fresh ones (not the backlog)."""
    ws = ws_connect(gcs)
    try:
        ws.send(json.dumps({"type": "seen", "telemetry": 0, "cloud": 0}))  # before any telemetry was read
        seqs = []
        ws.settimeout(1.5)
        try:
            while True:
                raw = ws.recv()
                if isinstance(raw, str) and json.loads(raw)["type"] == "telemetry":
                    seqs.append(json.loads(raw)["seq"])
        except websocket.WebSocketTimeoutException:
            pass
        assert len(seqs) == IN_FLIGHT["telemetry"] < 20  # 1.5 s at 50 Hz would be 75
        ws.send(json.dumps({"type": "seen", "telemetry": len(seqs), "cloud": 0}))
        assert receive(ws, "telemetry", timeout=2)["seq"] > seqs[-1] + 10
    finally:
        ws.close()


def test_tunnel_start_restarts_the_run_and_every_tab_gets_the_new_scene():
    with GcsProcess("vehicle", "--speed", "inf", "--set", "planner.auto_disarm_s=0") as g:  # not for the tunnel
        a, b = ws_connect(g), ws_connect(g)
        try:
            assert receive(a, "hello")["scene"]["regions"] == []
            receive(b, "hello")
            a.send(json.dumps({"type": "command", "id": 1, "command": {"command": "tunnel_start"}}))
            hello = receive(b, "hello", timeout=30)  # the other tab too
            assert hello["scene"]["scenario"] == "tunnel"
            # the true course is neither drawn nor offered: the gates are those the vehicle detects, as it does
            assert not any(m["label"] == "tunnel_frame" for m in hello["scene"]["meshes"])
            assert hello["scene"]["regions"] == [] and hello["scene"]["gates"] == []  # nothing detected yet
            assert receive(a, "ack", timeout=30, pred=lambda m: m["id"] == 1)["result"] == "accepted"
            a.send(json.dumps({"type": "command", "id": 2, "command": {"command": "sim_restart", "scenario": "nope"}}))
            ack = receive(a, "ack", timeout=30, pred=lambda m: m["id"] == 2)
            assert ack["result"] == "failed" and "nope" in ack["message"]
            # the tunnel run goes on: its mission's state machine shows in the event log
            assert receive(
                b,
                "events",
                timeout=30,
                pred=lambda m: any(
                    e["kind"] == "mission" and e["message"].startswith("mission initialise") for e in m["events"]
                ),
            )
            # and the gates its detector finds reach the tabs as it finds them
            found = receive(b, "gates", timeout=60, pred=lambda m: len(m["gates"]) > 0)
            assert found["frame"] == "estimated"
            assert [g["name"] for g in found["gates"]] == [f"gate{k + 1}" for k in range(len(found["gates"]))]
            # and they become the mission regions a new tab is offered
            c = ws_connect(g)
            try:
                regions = receive(c, "hello")["scene"]["regions"]
                assert [r["name"] for r in regions][: len(found["gates"])] == [x["name"] for x in found["gates"]]
            finally:
                c.close()
        finally:
            a.close()
            b.close()


@pytest.mark.parametrize(
    ("args", "named"),
    [(["nope"], "nope"), (["--speed", "20"], "speed"), (["--set", "controller.kind=zzz"], "controller.kind")],
)
def test_bad_arguments_exit_2_naming_them(args, named):
    import subprocess
    import sys

    r = subprocess.run(
        [
            sys.executable,
            "-c",
            "import sys; from cufund.apps.cli import main; sys.exit(main(sys.argv[1:]))",
            "gcs",
            *args,
            "--port",
            "0",
        ],
        check=False,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2 and named in r.stderr and r.stdout == ""
