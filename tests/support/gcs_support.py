"""Helpers for the ground-station tests: reading a tab's WebSocket."""

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
