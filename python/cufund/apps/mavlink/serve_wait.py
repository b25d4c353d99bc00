"""What a served vehicle or fleet does around its run: set the link-loss timeout it was given, warn when a link is
exposed beyond loopback, wait for the end (shared by :mod:`.serve_cli` and :mod:`.fleet_serve`)."""

from __future__ import annotations

import math
import signal
import sys
import threading
import time
from collections.abc import Iterable
from typing import Any


def set_link_loss_timeout(runs: dict[str, Any], timeout_s: float) -> str:
    """Sets PX4's ``COM_DL_LOSS_T`` to ``timeout_s`` [s] on each live run of ``runs`` (by name; "" for a single
    vehicle) through its commander, as a ground station's PARAM_SET would. Returns "" when every one took it, else
    the first refusal (``--link-loss-timeout (name): why``)."""
    cmd = {"command": "set_param", "name": "COM_DL_LOSS_T", "value": float(timeout_s)}
    for name, run in runs.items():
        ack = run.submit(cmd).result(timeout=10.0)
        if ack.result != "accepted":
            return f"--link-loss-timeout{f' ({name})' if name else ''}: {ack.message}"
    return ""


def warn_exposed(links: Iterable[Any]) -> None:
    """A warning on stderr for each of ``links`` bound beyond the loopback interface."""
    for lk in links:
        host = lk.local_address[0]
        if not host.startswith("127."):
            print(
                f"cufund serve: warning: {lk.address.mode}:{lk.address.host}:{lk.address.port} listens on "
                f"{host or '0.0.0.0'}: other machines can command this vehicle",
                file=sys.stderr,
                flush=True,
            )


def wait_until_stopped(duration: float | None) -> None:
    """Returns after ``duration`` wall-clock seconds (None: never) or at Ctrl-C / SIGTERM (the previous handlers
    restored on the way out)."""
    stop = threading.Event()
    previous: dict[signal.Signals, Any] = {}
    try:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                previous[sig] = signal.signal(sig, lambda *_: stop.set())
        deadline = math.inf if duration is None else time.monotonic() + duration
        while not stop.is_set() and time.monotonic() < deadline:
            stop.wait(0.2)
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
