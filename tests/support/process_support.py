"""Shared helpers of the tests that drive real programs as subprocesses (``cufund serve``, MAVProxy): starting them
with their output merged and unbuffered, reading that output in order with timeouts, and stopping them for sure
(terminate, then kill; pipes closed), so that a hang is a failure and never a stuck test."""

from __future__ import annotations

import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

BIN = Path(sys.executable).parent
"""The venv's bin folder (``cufund``, ``mavproxy.py``, ``mavsdk_server``)."""


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONUNBUFFERED": "1"}


def cufund_serve(*args: str) -> subprocess.Popen:
    """``cufund serve ARGS...``, its stdout and stderr merged into one text pipe."""
    return subprocess.Popen(
        [str(BIN / "cufund"), "serve", *args], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=_env()
    )


def mavproxy(port: int, state_dir: Path) -> subprocess.Popen:
    """MAVProxy as a ground station listening on udpin:127.0.0.1:``port`` (MAVLink 2, its state files in
    ``state_dir``), commanded through its stdin; read its output with :class:`ProcessOutput`."""
    return subprocess.Popen(
        [
            str(BIN / "mavproxy.py"),
            f"--master=udpin:127.0.0.1:{port}",
            "--mav20",
            f"--state-basedir={state_dir}",
            "--default-modules=link,cmdlong,arm,mode",
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=_env(),
        cwd=state_dir,
    )


def kill(p: subprocess.Popen, pumped: bool = False) -> str:
    """Stops ``p`` (terminate, then kill) and closes its pipes; its remaining output unless another thread reads
    it (``pumped``)."""
    if p.poll() is None:
        p.terminate()
    try:
        out = "" if pumped else p.communicate(timeout=5)[0]
        p.wait(5)
    except subprocess.TimeoutExpired:
        p.kill()
        out = "" if pumped else p.communicate()[0]
        p.wait(5)
    for f in (p.stdin, p.stdout):
        if f is not None:
            f.close()
    return out or ""


def interrupt(p: subprocess.Popen, timeout: float = 15.0) -> str:
    """Stops ``p`` as Ctrl-C does (SIGINT) and gives it ``timeout`` s to exit by itself, so that its exit code is
    its own (a SIGTERM sent at once could land in its shutdown and make it -15); then as :func:`kill`. Its
    remaining output (not for a process whose output another thread reads)."""
    if p.poll() is None:
        p.send_signal(signal.SIGINT)
    try:
        out = p.communicate(timeout=timeout)[0]
    except subprocess.TimeoutExpired:
        return kill(p)
    for f in (p.stdin, p.stdout):
        if f is not None:
            f.close()
    return out or ""


class ProcessOutput:
    """A subprocess's merged output, searched in order with timeouts (prompts share lines with messages, so the
    search goes by position in the text, not by line)."""

    def __init__(self, p: subprocess.Popen) -> None:
        self.q: queue.Queue[str] = queue.Queue()
        self.text = ""
        self.pos = 0
        threading.Thread(target=self._pump, args=(p,), daemon=True).start()

    def _pump(self, p: subprocess.Popen) -> None:
        for line in p.stdout:  # type: ignore[union-attr]
            self.q.put(line)

    def expect(self, pattern: str, timeout: float) -> str:
        end = time.monotonic() + timeout
        rx = re.compile(pattern)
        while True:
            m = rx.search(self.text, self.pos)
            if m:
                self.pos = m.end()
                return m.group(0)
            try:
                self.text += self.q.get(timeout=max(end - time.monotonic(), 0.01))
            except queue.Empty:
                if time.monotonic() >= end:
                    raise AssertionError(
                        f"{pattern!r} not seen within {timeout} s; output:\n{self.text[-3000:]}"
                    ) from None
