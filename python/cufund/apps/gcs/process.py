"""``cufund gcs`` in a subprocess, for scripts, tests and benchmarks: started, its URL read from the first line,
stopped (SIGTERM, then SIGKILL) on exit.

    with GcsProcess("vehicle", "--speed", "3") as gcs:
        requests.post(gcs.base + "/api/command", json={"command": "arm"}, headers=gcs.auth)
"""

from __future__ import annotations

import os
import select
import subprocess
import sys
import time
from typing import Any, Self

__all__ = ["GcsProcess", "wait_for"]

_BOOT = (
    "import os, signal, sys\n"
    "try:\n"  # the server dies with the process that started it (a test runner killed without teardown)
    "    import ctypes; ctypes.CDLL(None).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG (Linux)\n"
    "except (OSError, AttributeError):\n"
    "    pass\n"
    "if os.getppid() != int(os.environ.get('CUFUND_GCS_PARENT', os.getppid())):\n"
    "    sys.exit(1)  # the parent was gone before the signal was armed\n"
    "from cufund.apps.cli import main; sys.exit(main(sys.argv[1:]))"
)
"""The subprocess's bootstrap: ``cufund`` with a parent-death signal, so a server outlives no test run."""


class GcsProcess:
    """``cufund gcs SCENARIO *args --port 0`` in a subprocess (its own session, so stopping it stops it all)."""

    def __init__(self, scenario: str = "vehicle", *args: str, timeout: float = 60.0, cwd: str | None = None) -> None:
        self.cwd = cwd
        """The directory the server runs in (its run directory: ``sim_restart`` may load YAML files under it)."""
        self.argv = [
            sys.executable,
            "-c",
            _BOOT,
            "gcs",
            scenario,
            "--port",
            "0",
            *args,
        ]
        self.timeout = float(timeout)
        self.proc: subprocess.Popen | None = None
        self.url = self.base = self.token = ""
        self.first_line = ""

    @property
    def auth(self) -> dict[str, str]:
        """The ``Authorization: Bearer`` header."""
        return {"Authorization": f"Bearer {self.token}"}

    @property
    def pid(self) -> int:
        assert self.proc is not None
        return self.proc.pid

    def start(self) -> Self:
        self.proc = subprocess.Popen(
            self.argv,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
            cwd=self.cwd,
            env={**os.environ, "PYTHONUNBUFFERED": "1", "CUFUND_GCS_PARENT": str(os.getpid())},
        )
        assert self.proc.stdout is not None
        ready, _, _ = select.select([self.proc.stdout], [], [], self.timeout)
        line = self.proc.stdout.readline() if ready else ""
        if not line.startswith("GCS: "):
            err = self.stop()
            raise RuntimeError(f"cufund gcs did not start within {self.timeout:g} s: {line!r} {err[-2000:]}")
        self.first_line = line.rstrip("\n")
        self.url = self.first_line[len("GCS: ") :]
        self.base, _, self.token = self.url.partition("/?token=")
        return self

    def stop(self) -> str:
        """Stops the server; returns what it wrote on stderr ("" when already stopped)."""
        if self.proc is None or self.proc.stderr is None or self.proc.stderr.closed:
            return ""
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
        err = self.proc.stderr.read()
        for f in (self.proc.stdout, self.proc.stderr):
            if f is not None:
                f.close()
        return err or ""

    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


def wait_for(predicate: Any, timeout: float, interval: float = 0.05) -> Any:
    """Polls ``predicate()`` until it returns something truthy (returned) or ``timeout`` [s] passes (None)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(interval)
    return None
