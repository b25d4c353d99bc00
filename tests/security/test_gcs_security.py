"""Security of the web ground station (`cufund gcs`) and its Foxglove server, probed with real clients
(websocket-client, urllib, raw sockets) against a `cufund gcs` subprocess, all on 127.0.0.1: websocket clients that
never read cannot grow the server's memory without bound (they are dropped, counted and logged), the Foxglove
server wants the token and a local Origin, every malformed input gets an ``error`` reply or a 4xx naming the
problem (never a 500, a traceback, an unretrieved task exception or the token in a log line), ``sim_restart``
loads nothing outside the built-in scenarios and the run directory, and a POST from another Origin is refused."""

import json
import socket
import struct
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest

from cufund.apps.gcs import GcsProcess
from cufund.apps.gcs.process import wait_for
from gcs_support import receive

websocket = pytest.importorskip("websocket")  # websocket-client (test extras)

FLOOD_CLIENTS = 5
FLOOD_SECONDS = 20.0
"""At most this long: the flood ends as soon as the server has dropped every flooding client."""
PING_PAD = 40_000
"""Bytes of padding per ping: under the incoming message cap, so the server answers every one."""
RSS_GROWTH_BOUND_MB = 60.0
"""The server's peak RSS over its RSS before the flood. The unbounded queues of the old server grew it by 492 MB
(208 MB in a second run) in this test's 4 s; with the per-client bound (4 MiB) the growth measured was 22 MB."""


@pytest.fixture(scope="module")
def gcs():
    with GcsProcess("vehicle", "--speed", "1", "--set", "planner.auto_disarm_s=0") as g:
        yield g


def reset_peak_rss(pid) -> bool:
    """Resets the process's VmHWM to its current RSS (Linux: 5 > /proc/PID/clear_refs), so that a later VmHWM is the
    peak since now and not a start-up peak; False where the kernel does not allow it."""
    try:
        Path(f"/proc/{pid}/clear_refs").write_text("5")
    except OSError:
        return False
    return True


def peak_rss_mb(pid, sampled_mb: float, reset: bool) -> float:
    """The peak RSS since :func:`reset_peak_rss` (or the largest sample, where the reset was not allowed)."""
    return max(sampled_mb, rss_mb(pid, "VmHWM")) if reset else sampled_mb


def rss_mb(pid, key="VmRSS"):
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith(key + ":"):
            return int(line.split()[1]) / 1024.0
    raise AssertionError(f"no {key} for pid {pid}")


def http(gcs, path, body=None, headers=None, token=True, method=None):
    url = gcs.base + path + (f"?token={gcs.token}" if token else "")
    req = urllib.request.Request(url, data=body, headers=headers or {}, method=method)
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, r.read()
    except urllib.error.HTTPError as e:
        return e.code, e.read()


def ws_connect(gcs, **kw):
    kw.setdefault("origin", gcs.base)
    return websocket.create_connection(
        gcs.base.replace("http://", "ws://") + f"/ws?token={gcs.token}", timeout=10, **kw
    )


def serving(gcs):
    """A new tab gets telemetry."""
    ws = ws_connect(gcs)
    try:
        return receive(ws, "telemetry")
    finally:
        ws.close()


def stats(gcs):
    status, body = http(gcs, "/api/stats")
    assert status == 200
    return json.loads(body)


def closed_by_server(ws, timeout=5.0):
    """True when the server ends the connection (a close frame or the socket closed) within ``timeout``."""
    end = time.monotonic() + timeout
    ws.settimeout(0.5)
    while time.monotonic() < end:
        try:
            opcode, _ = ws.recv_data(control_frame=True)
        except websocket.WebSocketTimeoutException:
            continue
        except (websocket.WebSocketConnectionClosedException, ConnectionError, OSError):
            return True
        if opcode == websocket.ABNF.OPCODE_CLOSE:
            return True
    return False


# ---- memory: clients that never read ----------------------------------------------------------------------------
def test_non_reading_clients_flooding_pings_are_dropped_and_memory_stays_bounded(gcs):
    assert serving(gcs)  # the server is up and broadcasting
    before = rss_mb(gcs.pid)
    reset = reset_peak_rss(gcs.pid)
    sampled = before
    dropped0 = stats(gcs).get("dropped_clients", 0)
    small_rcvbuf = ((socket.SOL_SOCKET, socket.SO_RCVBUF, 4096),)
    clients = [ws_connect(gcs, sockopt=small_rcvbuf) for _ in range(FLOOD_CLIENTS)]
    for c in clients:
        c.settimeout(1.0)
    ping = json.dumps({"type": "ping", "id": 1, "pad": "x" * PING_PAD})
    alive = set(range(FLOOD_CLIENTS))
    end = time.monotonic() + FLOOD_SECONDS
    sent = 0
    while alive and time.monotonic() < end:
        for k in list(alive):
            try:
                clients[k].send(ping)
                sent += 1
            except (websocket.WebSocketException, OSError):
                alive.discard(k)  # the server hung up: it dropped this client
        sampled = max(sampled, rss_mb(gcs.pid))
    peak = peak_rss_mb(gcs.pid, sampled, reset)
    growth = peak - before
    print(
        f"flood: {sent} pings of {PING_PAD} B from {FLOOD_CLIENTS} non-reading clients in <= {FLOOD_SECONDS} s; "
        f"RSS {before:.0f} MB before, peak {peak:.0f} MB (+{growth:.0f} MB); {len(alive)} still connected"
    )
    for c in clients:
        c.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))  # vanish: RST, no handshake
        c.sock.close()
    assert sent > 200  # the flood was a flood
    assert growth < RSS_GROWTH_BOUND_MB
    # every flooding client was dropped and counted (and logged: see the log test); the server goes on serving
    assert wait_for(lambda: stats(gcs).get("dropped_clients", 0) - dropped0 >= FLOOD_CLIENTS, 10)
    assert gcs.alive()
    assert serving(gcs)


def test_an_oversized_message_closes_the_socket(gcs):
    ws = ws_connect(gcs)
    receive(ws, "hello")
    ws.send(json.dumps({"type": "ping", "id": 2, "pad": "x" * 900_000}))
    try:
        assert closed_by_server(ws)
    finally:
        ws.shutdown()
    assert gcs.alive() and serving(gcs)


# ---- error paths ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "bad",
    [
        '{"type": "seen", "telemetry": Infinity}',
        '{"type": "seen", "telemetry": NaN, "cloud": 0}',
        '{"type": "seen", "telemetry": 1e400}',
        "[" * 30_000 + "]" * 30_000,  # under the message size cap, deeper than Python's recursion limit
        '{"type": "layers", "cloud": ' + "[" * 20_000 + "]" * 20_000 + "}",
        '{"type": "seen", "telemetry": ' + "9" * 4000 + "}",
    ],
)
def test_malformed_websocket_messages_get_an_error_reply_and_the_socket_stays_open(gcs, bad):
    ws = ws_connect(gcs)
    try:
        receive(ws, "hello")
        ws.send(bad)
        assert receive(ws, "error")["message"]
        ws.send(json.dumps({"type": "ping", "id": 99}))
        assert receive(ws, "pong", pred=lambda m: m["id"] == 99)  # still served
    finally:
        ws.close()


@pytest.mark.parametrize(
    "body",
    [
        b"[" * 30_000 + b"]" * 30_000,
        b'{"command": "sim_speed", "speed": ' + b"9" * 4000 + b"}",
        b'{"command": "goto", "p_W": [' + b"9" * 4000 + b", 0, 1]}",
        b'{"command": "takeoff", "altitude": ' + b"9" * 4000 + b"}",
        b'{"command": "goto", "p_W": [1e400, 0, 1]}',
        b'{"command": "mission_preview", "formula": "F(a)", "regions": [{"name": "a", "centre_W": ['
        + b"9" * 4000
        + b', 0, 0], "radius": 0.3}]}',
        b"\xff\xfe not utf-8",
    ],
)
def test_malformed_http_commands_are_4xx_with_a_message(gcs, body):
    status, reply = http(gcs, "/api/command", body, headers={"Content-Type": "application/json"})
    assert 400 <= status < 500, (status, reply[:300])
    assert json.loads(reply)["message"]


def test_no_traceback_token_or_unretrieved_task_in_the_logs():
    """Everything above that once logged a traceback (with the token in its request line) or left failed tasks
    behind, against a fresh server whose stderr is read at the end."""
    with GcsProcess("vehicle", "--speed", "1") as g:
        ws = ws_connect(g)
        receive(ws, "hello")
        for bad in ('{"type": "seen", "telemetry": Infinity}', "[" * 30_000 + "]" * 30_000):
            ws.send(bad)
            receive(ws, "error")
        ws.close()
        for body in (b"[" * 30_000 + b"]" * 30_000, b'{"command": "sim_speed", "speed": ' + b"9" * 4000 + b"}"):
            assert 400 <= http(g, "/api/command", body)[0] < 500
        assert http(g, "/api/command", b'{"command": "fly"}')[0] == 400  # 4xx lines carry the URL too
        # slow clients that vanish with writes pending
        clients = [ws_connect(g, sockopt=((socket.SOL_SOCKET, socket.SO_RCVBUF, 4096),)) for _ in range(3)]
        ping = json.dumps({"type": "ping", "id": 1, "pad": "x" * PING_PAD})
        for _ in range(100):
            for c in clients:
                try:
                    c.send(ping)
                except (websocket.WebSocketException, OSError):
                    pass
        for c in clients:
            c.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            c.sock.close()
        time.sleep(0.5)  # let the server see the resets (not a timing assertion)
        assert serving(g)  # and go on
        err = g.stop()
    assert g.token not in err
    drops = [line for line in err.splitlines() if "dropped a ground station tab that does not read" in line]
    assert len(drops) <= len(clients)  # one line per dropped tab, if it was dropped before it vanished
    assert "Traceback" not in err and "Task exception was never retrieved" not in err, err[-3000:]


# ---- sim_restart: built-in names and the run directory only -----------------------------------------------------
@pytest.mark.parametrize(
    "path",
    [
        "/etc/passwd",
        "/etc/hostname",
        "../../../../etc/passwd",
        "/proc/self/environ",
        "/etc/os-release.yaml",
        "~/.bashrc",
    ],
)
def test_sim_restart_outside_the_run_directory_is_refused_without_echo(gcs, path):
    secret = Path("/etc/passwd").read_text().splitlines()[0]
    ws = ws_connect(gcs)
    try:
        receive(ws, "hello")
        ws.send(json.dumps({"type": "command", "id": 5, "command": {"command": "sim_restart", "scenario": path}}))
        ack = receive(ws, "ack", timeout=30, pred=lambda m: m["id"] == 5)
    finally:
        ws.close()
    assert ack["result"] == "failed"
    assert "built-in" in ack["message"] or "run directory" in ack["message"]
    assert secret not in ack["message"] and "root:" not in ack["message"]
    status, body = http(gcs, "/api/command", json.dumps({"command": "sim_restart", "scenario": path}).encode())
    assert status == 400 and b"root:" not in body and secret.encode() not in body


def test_sim_restart_of_a_bad_yaml_in_the_run_directory_does_not_echo_it(tmp_path):
    secret = "hunter2-secret-value"
    bad = tmp_path / "bad.yaml"
    bad.write_text(f"{secret}: [1, 2]\nvehicle: {secret}\n")
    g = GcsProcess("vehicle", "--speed", "1", cwd=str(tmp_path)).start()  # its run directory: where it started
    try:
        ws = ws_connect(g)
        receive(ws, "hello")
        ws.send(json.dumps({"type": "command", "id": 6, "command": {"command": "sim_restart", "scenario": "bad.yaml"}}))
        ack = receive(ws, "ack", timeout=30, pred=lambda m: m["id"] == 6)
        assert ack["result"] == "failed" and "bad.yaml" in ack["message"] and secret not in ack["message"]
        ws.close()
    finally:
        g.stop()


# ---- Origin and Host ----------------------------------------------------------------------------------------------
def test_a_post_from_another_origin_is_refused(gcs):
    body = json.dumps({"command": "sim_pause"}).encode()
    for origin in ("http://evil.example", "null", gcs.base.replace("127.0.0.1", "127.0.0.1.evil.example")):
        status, _ = http(gcs, "/api/command", body, headers={"Content-Type": "text/plain", "Origin": origin})
        assert status == 403, origin
    status, _ = http(gcs, "/api/command", body, headers={"Host": "evil.example"})  # DNS rebinding
    assert status == 403
    # the same origin, or a script that sends none, with the token: accepted
    assert (
        http(gcs, "/api/command", json.dumps({"command": "sim_resume"}).encode(), headers={"Origin": gcs.base})[0]
        == 200
    )
    assert http(gcs, "/api/command", json.dumps({"command": "sim_resume"}).encode())[0] == 200


def test_a_websocket_from_another_origin_is_refused(gcs):
    with pytest.raises(websocket.WebSocketBadStatusException) as e:
        ws_connect(gcs, origin="http://evil.example")
    assert e.value.status_code == 403


# ---- Foxglove ---------------------------------------------------------------------------------------------------
def test_foxglove_requires_the_token_and_a_local_origin():
    with GcsProcess("vehicle", "--speed", "1", "--foxglove", "--foxglove-port", "0") as g:
        line = g.proc.stdout.readline().strip()
        assert line.startswith("Foxglove: ws://127.0.0.1:")
        url = line.split()[1]
        bare = url.split("?")[0]
        for kw in (
            {"url": bare},
            {"url": bare + "?token=wrong"},
            {"url": url, "origin": "http://evil.example"},
            {"url": url, "origin": "null"},
        ):
            with pytest.raises(websocket.WebSocketBadStatusException) as e:
                websocket.create_connection(
                    kw["url"],
                    timeout=10,
                    subprotocols=["foxglove.sdk.v1"],
                    **({"origin": kw["origin"]} if "origin" in kw else {}),
                )
            assert e.value.status_code in (401, 403), kw
        ws = websocket.create_connection(url, timeout=10, subprotocols=["foxglove.websocket.v1"])  # Studio's
        try:
            assert ws.getsubprotocol() == "foxglove.websocket.v1"
            assert json.loads(ws.recv())["op"] == "serverInfo"
            ws.send("not json")
            assert json.loads(ws.recv())["op"] in ("status", "advertise")
        finally:
            ws.close()
        err = g.stop()
    assert g.token not in err and "Traceback" not in err


def test_a_foxglove_client_that_does_not_read_is_dropped():
    """Every malformed message gets a status reply; a client that sends them and never reads is dropped once its
    replies pile up, and the server goes on serving others."""
    with GcsProcess("vehicle", "--speed", "1", "--foxglove", "--foxglove-port", "0") as g:
        url = g.proc.stdout.readline().split()[1]
        before = rss_mb(g.pid)
        # a send that blocks while a loaded server catches up is not a drop: only the server closing the socket is
        # (a 2 s send timeout counted a slow server as a dropping one on a busy CI machine)
        flooder = websocket.create_connection(
            url, timeout=30, subprotocols=["foxglove.sdk.v1"], sockopt=((socket.SOL_SOCKET, socket.SO_RCVBUF, 4096),)
        )
        garbage = "{}"  # small: many replies (each longer than the message) per second
        reset, sampled = reset_peak_rss(g.pid), before
        dropped = False
        end = time.monotonic() + FLOOD_SECONDS
        while time.monotonic() < end:
            try:
                flooder.send(garbage)
            except (websocket.WebSocketException, OSError):
                dropped = True
                break
            sampled = max(sampled, rss_mb(g.pid))
        growth = peak_rss_mb(g.pid, sampled, reset) - before
        flooder.shutdown()
        assert dropped and growth < RSS_GROWTH_BOUND_MB
        ws = websocket.create_connection(url, timeout=10, subprotocols=["foxglove.sdk.v1"])
        try:
            assert json.loads(ws.recv())["op"] == "serverInfo"
        finally:
            ws.close()
        err = g.stop()
    assert "dropped a Foxglove client that does not read" in err and "Traceback" not in err
