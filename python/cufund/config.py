"""Loading typed, frozen configuration dataclasses from plain dicts and YAML, with clear errors."""

from __future__ import annotations

import dataclasses
import math
import numbers
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import yaml

T = TypeVar("T")


class ConfigError(ValueError):
    """A configuration value or key is wrong; the message names the field and what was expected."""


def from_dict(cls: type[T], data: Any, where: str | None = None) -> T:
    """Builds dataclass ``cls`` from a mapping, rejecting unknown keys by name.

    Field conversion and validation are the dataclass's own (its ``__post_init__``); this only checks
    that ``data`` is a mapping whose keys are fields of ``cls``.
    """
    where = where or cls.__name__
    if not isinstance(data, dict):
        raise ConfigError(f"{where} must be a mapping of field names to values, got {type(data).__name__}")
    names = [f.name for f in dataclasses.fields(cls) if f.init]  # type: ignore[arg-type]
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise ConfigError(f"unknown key {unknown[0]!r} in {where}; expected one of: {', '.join(names)}")
    required = [f.name for f in dataclasses.fields(cls)  # type: ignore[arg-type]
                if f.init and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
    missing = [name for name in required if name not in data]
    if missing:
        raise ConfigError(f"missing key {missing[0]!r} in {where}; required: {', '.join(required)}")
    return cls(**data)


def nested(cls: type[T], value: Any, where: str) -> T:
    """A dataclass field that holds another dataclass: ``value`` itself if it is a ``cls``, else ``cls`` built
    from the mapping ``value`` by :func:`from_dict` (None: all defaults)."""
    if isinstance(value, cls):
        return value
    return from_dict(cls, {} if value is None else value, where)


def check_real_fields(obj: Any, where: str, positive: bool = False, unit: str = "",
                      names: tuple[str, ...] | None = None) -> None:
    """Makes the fields ``names`` (default: every field) of the frozen dataclass ``obj`` floats, requiring a
    finite number >= 0 (> 0 when ``positive``); the error names ``where.field``."""
    bound = "> 0" if positive else ">= 0"
    for name in names if names is not None else [f.name for f in dataclasses.fields(obj)]:
        v = getattr(obj, name)
        if (isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v)
                or v < 0 or (positive and v == 0)):
            raise ConfigError(f"{where}.{name} must be a finite number {bound}{unit}, got {v!r}")
        object.__setattr__(obj, name, float(v))


def real_number(name: str, value: Any) -> float:
    """``value`` as a float if it is a real number (not a bool); else a ConfigError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, (numbers.Real, np.floating, np.integer)):
        raise ConfigError(f"{name} must be a real number, got {type(value).__name__} {value!r}")
    return float(value)


def vector3(name: str, value: Any, unit: str = "", finite: bool = False) -> tuple[float, float, float]:
    """``value`` as 3 floats (``finite``: all finite); else a ConfigError naming ``name`` and ``unit``."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as e:
        raise ConfigError(f"{name} must be 3 real numbers{unit}: {e}") from None
    if a.shape != (3,) or (finite and not np.all(np.isfinite(a))):
        what = "finite real numbers" if finite else "real numbers"
        raise ConfigError(f"{name} must be 3 {what}{unit}, got {value!r}")
    return (float(a[0]), float(a[1]), float(a[2]))


def load_yaml(path: str | Path) -> Any:
    """Parses a YAML file; a syntax error names the file and line."""
    path = Path(path)
    try:
        with path.open("r", encoding="utf-8") as f:
            return yaml.safe_load(f)
    except yaml.YAMLError as e:
        raise ConfigError(f"{path}: invalid YAML: {e}") from e


def to_dict(obj: Any) -> dict[str, Any]:
    """A dataclass as plain Python data (nested dataclasses become dicts, tuples lists) suitable for
    ``yaml.safe_dump``."""

    def plain(x: Any) -> Any:
        if dataclasses.is_dataclass(x) and not isinstance(x, type):
            return {f.name: plain(getattr(x, f.name)) for f in dataclasses.fields(x)}
        if isinstance(x, (tuple, list)):
            return [plain(v) for v in x]
        return x

    return {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
