"""An append-only, thread-safe event log (mode changes, refusals, mission progress, collisions, errors)."""

from __future__ import annotations

import threading
from typing import Any

__all__ = ["EventLog"]


class EventLog:
    """Events as dicts ``{"index", "t", "kind", "message", ...}``, appended from the simulation thread and read
    from any other; ``index`` counts from 0, so a reader catches up with :meth:`since`."""

    def __init__(self, maxlen: int = 100000) -> None:
        self._events: list[dict[str, Any]] = []
        self._lock = threading.Lock()
        self._offset = 0  # events dropped from the front when the log grows past maxlen
        self.maxlen = int(maxlen)

    def append(self, t: float, kind: str, message: str, **data: Any) -> dict[str, Any]:
        with self._lock:
            e = {
                "index": self._offset + len(self._events),
                "t": float(t),
                "kind": str(kind),
                "message": str(message),
                **data,
            }
            self._events.append(e)
            if len(self._events) > self.maxlen:
                drop = len(self._events) - self.maxlen
                del self._events[:drop]
                self._offset += drop
            return e

    def since(self, index: int = 0) -> list[dict[str, Any]]:
        """Events with ``index >= index`` (copies)."""
        with self._lock:
            start = max(int(index) - self._offset, 0)
            return [dict(e) for e in self._events[start:]]

    def of_kind(self, kind: str) -> list[dict[str, Any]]:
        with self._lock:
            return [dict(e) for e in self._events if e["kind"] == kind]

    def __len__(self) -> int:
        with self._lock:
            return self._offset + len(self._events)

    def __iter__(self):
        return iter(self.since(0))

    def __getitem__(self, i: int) -> dict[str, Any]:
        with self._lock:
            return dict(self._events[i])
