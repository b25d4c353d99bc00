"""The worker plugin of a sweep's local cluster (imported only where a cluster starts: it loads ``distributed``)."""

from __future__ import annotations

import signal
import threading
from typing import Any

from distributed.diagnostics.plugin import WorkerPlugin

__all__ = ["IgnoreInterrupts"]


class IgnoreInterrupts(WorkerPlugin):
    """Workers ignore SIGINT: a terminal's Ctrl-C reaches the whole process group, and the sweep (the client
    process) is the one that stops them, cleanly, after keeping what finished."""

    def setup(self, worker: Any) -> None:
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.SIG_IGN)
