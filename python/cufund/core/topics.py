"""Typed topics: a topic is its name (a ``str``, so it works wherever a name does) plus its message type."""

from __future__ import annotations

import builtins
from typing import Any

__all__ = ["TRUTH_PREFIX", "Topic", "is_truth"]

TRUTH_PREFIX = "/truth/"
"""Every topic under this namespace carries ground truth: only truth consumers (sensor models, recorders,
metrics, loggers, viewers) may read it once an estimator is configured."""


def is_truth(name: str) -> bool:
    """Whether topic ``name`` carries ground truth."""
    return name.startswith(TRUTH_PREFIX)


class Topic(str):
    """A topic name with its message type: ``Topic("/sensors/imu", Imu)``. The bus checks every message
    published on a typed topic against ``type``; it compares and hashes as its name."""

    type: builtins.type
    """The message class published on it (``object``: any)."""

    def __new__(cls, name: str, type: builtins.type = object) -> Topic:
        if not isinstance(name, str) or not name.startswith("/") or name.endswith("/") or "//" in name:
            raise ValueError(f"a topic name must be an absolute path like '/sensors/imu', got {name!r}")
        self = super().__new__(cls, name)
        self.type = type
        return self

    @property
    def name(self) -> str:
        return str(self)

    @property
    def truth(self) -> bool:
        """Whether it carries ground truth (it lies under ``/truth/``)."""
        return self.startswith(TRUTH_PREFIX)

    def __repr__(self) -> str:
        return f"Topic({str(self)!r}, {getattr(self.type, '__name__', self.type)})"

    def __reduce__(self) -> tuple[Any, ...]:
        return (Topic, (str(self), self.type))
