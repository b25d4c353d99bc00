"""Commands handed over between threads: any thread submits, the simulation thread applies them in order."""

from __future__ import annotations

import collections
from collections.abc import Callable
from concurrent.futures import Future
from typing import Any

from .commands import Command, CommandAck, parse_command

__all__ = ["CommandInbox"]


class CommandInbox:
    """A queue of (command, future); ``submit``, ``link_lost`` and ``link_regained`` are thread-safe."""

    def __init__(self) -> None:
        self._inbox: collections.deque[tuple[Command, Future | None]] = collections.deque()

    def submit(self, cmd: Any) -> Future:
        """Queues ``cmd`` (a dict, a name or a :class:`Command`) for the next step; returns a Future of its
        :class:`CommandAck`. Raises ``ValueError`` at once for a malformed command."""
        command = parse_command(cmd)
        fut: Future = Future()
        self._inbox.append((command, fut))
        return fut

    def link_lost(self) -> None:
        """The command link is gone: hold, then land after ``link_loss_timeout_s``."""
        self._inbox.append((Command("_link_lost"), None))

    def link_regained(self) -> None:
        """The link is back: no landing for link loss (the vehicle keeps holding)."""
        self._inbox.append((Command("_link_regained"), None))

    def drain(self, apply: Callable[[Command], CommandAck]) -> None:
        """Applies every queued command in order (on the simulation thread) and resolves its future. A command
        whose future the submitter cancelled before it was applied (it gave up waiting) is dropped, unapplied."""
        while self._inbox:
            cmd, fut = self._inbox.popleft()
            if fut is not None and (fut.done() or not fut.set_running_or_notify_cancel()):
                continue
            ack = apply(cmd)
            if fut is not None:
                fut.set_result(ack)

    def cancel_pending(self, why: str) -> None:
        """Fails every queued command (the run has ended)."""
        self.drain(lambda cmd: CommandAck(cmd.command, "failed", why))
