"""Exact JSON encoding of message field values (floats by their shortest round-trip repr, arrays with their dtype
and shape, enums and nested dataclasses by class), for the JSON channels of a log."""

from __future__ import annotations

import base64
import dataclasses
import enum
import importlib
import math
from typing import Any

import numpy as np

__all__ = ["class_path", "decode_value", "encode_value", "resolve_class"]

_SMALL_ARRAY = 64
"""Arrays up to this many finite elements are written as a list of numbers (plottable in Foxglove), larger ones
as base64 bytes."""


def class_path(cls: type) -> str:
    """``module:QualName`` of a class (what :func:`resolve_class` imports back)."""
    return f"{cls.__module__}:{cls.__qualname__}"


def resolve_class(path: str) -> type:
    """The class named by ``module:QualName``; ValueError naming it when it cannot be imported."""
    module_name, _, qualname = path.partition(":")
    try:
        obj: Any = importlib.import_module(module_name)
        for part in qualname.split("."):
            obj = getattr(obj, part)
    except (ImportError, AttributeError, ValueError) as exc:
        raise ValueError(f"the log names message class {path!r}, which cannot be imported here ({exc})") from exc
    if not isinstance(obj, type):
        raise ValueError(f"the log names {path!r} as a message class, but it is not a class")
    return obj


def encode_value(value: Any, where: str) -> Any:
    """A JSON-able, exactly invertible form of ``value``; TypeError naming ``where`` for what cannot be logged."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, enum.Enum):
        return {"$enum": class_path(type(value)), "value": encode_value(value.value, where)}
    if isinstance(value, int):
        return int(value)
    if isinstance(value, float):
        return float(value) if math.isfinite(value) else {"$float": repr(float(value))}
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "biufc":
            raise TypeError(f"{where}: cannot log an array of dtype {value.dtype}")
        out: dict[str, Any] = {"dtype": value.dtype.str, "shape": list(value.shape)}
        if value.size <= _SMALL_ARRAY and value.dtype.kind in "biuf" and np.isfinite(value).all():
            out["values"] = value.reshape(-1).tolist()
        else:
            out["base64"] = base64.b64encode(np.ascontiguousarray(value).tobytes()).decode()
        return {"$ndarray": out}
    if isinstance(value, np.generic):
        return {"$scalar": value.dtype.str, "value": encode_value(value.item(), where)}
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {"$dataclass": class_path(type(value)), "fields": encode_fields(value, where)}
    if isinstance(value, tuple):
        return {"$tuple": [encode_value(v, where) for v in value]}
    if isinstance(value, list):
        return [encode_value(v, where) for v in value]
    if isinstance(value, dict) and all(isinstance(k, str) for k in value):
        return {"$dict": {k: encode_value(v, where) for k, v in value.items()}}
    raise TypeError(f"{where}: cannot log a value of type {type(value).__name__} (numbers, strings, enums, numpy "
                    "arrays, lists, tuples, str-keyed dicts and dataclasses of those can be logged)")


def encode_fields(message: Any, where: str) -> dict[str, Any]:
    """Every dataclass field of ``message``, encoded."""
    return {f.name: encode_value(getattr(message, f.name), f"{where}.{f.name}")
            for f in dataclasses.fields(message)}


def decode_value(value: Any) -> Any:
    """Inverse of :func:`encode_value`."""
    if isinstance(value, list):
        return [decode_value(v) for v in value]
    if not isinstance(value, dict):
        return value
    if "$float" in value:
        return float(value["$float"])
    if "$ndarray" in value:
        spec = value["$ndarray"]
        dtype = np.dtype(spec["dtype"])
        if "values" in spec:
            array = np.array(spec["values"], dtype=dtype)
        else:
            array = np.frombuffer(base64.b64decode(spec["base64"]), dtype=dtype).copy()
        return array.reshape(spec["shape"])
    if "$enum" in value:
        return resolve_class(value["$enum"])(decode_value(value["value"]))
    if "$scalar" in value:
        return np.dtype(value["$scalar"]).type(decode_value(value["value"]))
    if "$dataclass" in value:
        return resolve_class(value["$dataclass"])(**decode_fields(value["fields"]))
    if "$tuple" in value:
        return tuple(decode_value(v) for v in value["$tuple"])
    if "$dict" in value:
        return {k: decode_value(v) for k, v in value["$dict"].items()}
    raise ValueError(f"unknown encoded value {sorted(value)!r}")


def decode_fields(fields: dict[str, Any]) -> dict[str, Any]:
    return {name: decode_value(v) for name, v in fields.items()}
