"""Which classes a log may name: reading a log never imports or calls anything the file names beyond this
allowlist.

A log names the class of each channel (its ``cufund.class`` metadata) and of enums and nested dataclasses inside
JSON messages (``$enum``, ``$dataclass``). Those names are looked up here, never imported: the allowed classes
are cufund's own messages and enums (:mod:`cufund.core.messages` and the dataclasses and enums their fields
hold), classes this process has logged itself, and user classes registered with :func:`register_message_class`;
a name an older cufund recorded (``cufund.messages:Imu``) is first mapped to its name now, as a string
(:func:`cufund.core.moved.new_class_path`). Any other name is a ValueError, so that a crafted ``run.mcap`` cannot make
``cufund replay`` run ``subprocess:Popen``.
"""

from __future__ import annotations

import dataclasses
import enum
import threading
import typing
from typing import Any

from cufund.core.moved import new_class_path

__all__ = ["class_path", "message_class", "note_logged", "register_message_class"]

_lock = threading.Lock()
_registered: dict[str, type] = {}
_builtin_done = False


def class_path(cls: type) -> str:
    """``module:QualName`` of a class (the name a log keeps)."""
    return f"{cls.__module__}:{cls.__qualname__}"


def _loggable(cls: Any) -> bool:
    return isinstance(cls, type) and (dataclasses.is_dataclass(cls) or issubclass(cls, enum.Enum))


def _nested(cls: type) -> list[type]:
    """The dataclasses and enums named in the type hints of dataclass ``cls``'s fields."""
    if not dataclasses.is_dataclass(cls):
        return []
    try:
        hints = typing.get_type_hints(cls)
    except Exception:  # unresolvable annotations name nothing we can trust
        return []
    out: list[type] = []
    stack = list(hints.values())
    while stack:
        hint = stack.pop()
        if _loggable(hint):
            out.append(hint)
        stack.extend(typing.get_args(hint))
    return out


def _add(cls: type) -> None:
    """``cls`` and the dataclasses and enums its fields name (caller holds the lock)."""
    todo = [cls]
    while todo:
        c = todo.pop()
        path = class_path(c)
        if _registered.get(path) is c:
            continue
        _registered[path] = c
        todo.extend(_nested(c))


def register_message_class(cls: type) -> type:
    """Allows logs to name ``cls`` (a dataclass or an enum; its nested dataclass and enum fields too), so that
    :func:`cufund.logs.read_mcap` rebuilds its messages. Returns ``cls`` (usable as a decorator). A class this
    process logs is registered when it is logged."""
    if not _loggable(cls):
        raise TypeError(f"register_message_class takes a dataclass or an enum class, got {cls!r}")
    with _lock:
        _add(cls)
    return cls


def _builtin() -> None:
    global _builtin_done
    if _builtin_done:
        return
    from cufund.core import messages

    with _lock:
        for obj in vars(messages).values():
            if _loggable(obj) and obj.__module__ == messages.__name__:
                _add(obj)
        _builtin_done = True


def message_class(path: Any, where: str) -> type:
    """The allowed class a log names by ``path`` (``module:QualName``); ValueError naming ``where`` (the channel)
    for any other name. Never imports a module the name chooses."""
    _builtin()
    if not isinstance(path, str):
        raise ValueError(f"{where}: a class name must be a string 'module:Class', got {type(path).__name__}")
    cls = _registered.get(path)
    if cls is None:
        cls = _registered.get(new_class_path(path))
    if cls is None:
        shown = path if len(path) <= 200 else path[:200] + "..."
        raise ValueError(
            f"{where} names the class {shown!r}, which is not an allowed message class (cufund's "
            "messages and classes registered with cufund.logs.register_message_class)"
        )
    return cls


_noted: dict[type, str] = {}
"""Classes already noted, with their names (the JSON encoder notes a class for every value it writes)."""


def note_logged(cls: type) -> str:
    """Registers ``cls`` as a class this process logs (a log it writes can be read back); returns its name."""
    path = _noted.get(cls)
    if path is None or _registered.get(path) is not cls:
        path = class_path(cls)
        if _registered.get(path) is not cls:
            register_message_class(cls)
        _noted[cls] = path
    return path
