"""Helpers for the ground-station tests: a tab's WebSocket (connecting, reading, commanding) and headless Chromium."""

from __future__ import annotations

import json
import time


def receive(ws, kind, timeout=10.0, pred=lambda m: True):
    """The next text message of ``kind`` satisfying ``pred`` (binary frames and other messages skipped); a
    TimeoutError when none comes within ``timeout`` [s] overall (messages that keep coming do not extend it)."""
    end = time.monotonic() + timeout
    while True:
        left = end - time.monotonic()
        if left <= 0:
            raise TimeoutError(f"no {kind!r} message satisfying the predicate within {timeout} s")
        ws.settimeout(left)
        raw = ws.recv()
        if isinstance(raw, bytes):
            continue
        m = json.loads(raw)
        if m["type"] == kind and pred(m):
            return m


def ws_connect(gcs, token=True):
    """A websocket to a :class:`cufund.apps.gcs.GcsProcess` as the page opens it (same origin)."""
    import websocket

    url = gcs.base.replace("http://", "ws://") + "/ws" + (f"?token={gcs.token}" if token else "")
    return websocket.create_connection(url, timeout=10, origin=gcs.base)


def command(ws, cmd, ident, timeout=30.0):
    """Sends ``cmd`` as command ``ident`` and returns its ``ack``."""
    ws.send(json.dumps({"type": "command", "id": ident, "command": cmd}))
    return receive(ws, "ack", timeout=timeout, pred=lambda m: m["id"] == ident)


CHROMEDRIVER = "/usr/bin/chromedriver"


def chromium(width=1000, height=650):
    """Debian's headless Chromium through selenium, with a window of ``width`` x ``height`` CSS pixels (software
    WebGL); the caller quits it."""
    import shutil

    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    for a in (
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        "--use-gl=swiftshader",
        "--enable-unsafe-swiftshader",
        f"--window-size={width},{height}",
        "--disable-dev-shm-usage",
    ):
        options.add_argument(a)
    options.binary_location = shutil.which("chromium")
    d = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    d.set_script_timeout(10)
    return d
