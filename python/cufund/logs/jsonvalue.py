"""Exact JSON encoding of message field values (floats by their shortest round-trip repr, arrays with their dtype
and shape, enums and nested dataclasses by class), for the JSON channels of a log."""

from __future__ import annotations

import base64
import dataclasses
import enum
import math
from typing import Any

import numpy as np

from .message_classes import class_path, message_class, note_logged

__all__ = ["class_path", "decode_value", "encode_value", "numeric_dtype"]

_SMALL_ARRAY = 64
"""Arrays up to this many finite elements are written as a list of numbers (plottable in Foxglove), larger ones
as base64 bytes."""


def encode_value(value: Any, where: str) -> Any:
    """A JSON-able, exactly invertible form of ``value``; TypeError naming ``where`` for what cannot be logged."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, enum.Enum):
        return {"$enum": note_logged(type(value)), "value": encode_value(value.value, where)}
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
        return {"$dataclass": note_logged(type(value)), "fields": encode_fields(value, where)}
    if isinstance(value, tuple):
        return {"$tuple": [encode_value(v, where) for v in value]}
    if isinstance(value, list):
        return [encode_value(v, where) for v in value]
    if isinstance(value, dict) and all(isinstance(k, str) for k in value):
        return {"$dict": {k: encode_value(v, where) for k, v in value.items()}}
    raise TypeError(
        f"{where}: cannot log a value of type {type(value).__name__} (numbers, strings, enums, numpy "
        "arrays, lists, tuples, str-keyed dicts and dataclasses of those can be logged)"
    )


def encode_fields(message: Any, where: str) -> dict[str, Any]:
    """Every dataclass field of ``message``, encoded."""
    return {f.name: encode_value(getattr(message, f.name), f"{where}.{f.name}") for f in dataclasses.fields(message)}


def numeric_dtype(text: Any, where: str) -> np.dtype:
    """The numeric dtype a log names (booleans, integers, floats, complex; no objects, strings or records)."""
    if not isinstance(text, str) or len(text) > 8:
        raise ValueError(f"{where}: a dtype must be a short numpy code like '<f8', got {text!r}")
    try:
        dtype = np.dtype(text)
    except TypeError as exc:
        raise ValueError(f"{where}: unknown dtype {text!r}") from exc
    if dtype.kind not in "biufc" or dtype.fields is not None or dtype.subdtype is not None:
        raise ValueError(f"{where}: dtype {text!r} is not numeric")
    return dtype


def _shape(value: Any, where: str) -> list[int]:
    if not (
        isinstance(value, list)
        and len(value) <= 32
        and all(isinstance(n, int) and not isinstance(n, bool) and 0 <= n < 2**40 for n in value)
    ):
        raise ValueError(f"{where}: an array shape must be a list of non-negative ints, got {value!r}")
    return value


def _mapping(value: Any, where: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ValueError(f"{where}: expected an object, got {type(value).__name__}")
    return value


def decode_value(value: Any, where: str = "a logged value") -> Any:
    """Inverse of :func:`encode_value`. Classes are looked up by :func:`cufund.logs.message_classes.message_class`
    (never imported by the name the data gives); a malformed value is a ValueError naming ``where``."""
    if isinstance(value, list):
        return [decode_value(v, where) for v in value]
    if not isinstance(value, dict):
        return value
    if "$float" in value:
        text = value["$float"]
        if text not in ("nan", "inf", "-inf"):
            raise ValueError(f"{where}: $float must be 'nan', 'inf' or '-inf', got {text!r}")
        return float(text)
    if "$ndarray" in value:
        spec = _mapping(value["$ndarray"], where)
        dtype = numeric_dtype(spec.get("dtype"), where)
        shape = _shape(spec.get("shape"), where)
        if "values" in spec:
            array = np.array(spec["values"], dtype=dtype)
        else:
            data = spec.get("base64")
            if not isinstance(data, str):
                raise ValueError(f"{where}: an array needs 'values' or 'base64'")
            raw = base64.b64decode(data, validate=True)
            if len(raw) % dtype.itemsize:
                raise ValueError(f"{where}: {len(raw)} bytes are not whole {dtype} elements")
            array = np.frombuffer(raw, dtype=dtype).copy()
        if array.size != math.prod(shape):
            raise ValueError(f"{where}: {array.size} elements do not fill the shape {shape}")
        return array.reshape(shape)
    if "$enum" in value:
        cls = message_class(value["$enum"], where)
        if not issubclass(cls, enum.Enum):
            raise ValueError(f"{where}: {value['$enum']!r} is not an enum")
        return cls(decode_value(value.get("value"), where))
    if "$scalar" in value:
        return numeric_dtype(value["$scalar"], where).type(decode_value(value.get("value"), where))
    if "$dataclass" in value:
        cls = message_class(value["$dataclass"], where)
        if not dataclasses.is_dataclass(cls):
            raise ValueError(f"{where}: {value['$dataclass']!r} is not a dataclass")
        return cls(**decode_fields(_mapping(value.get("fields"), where), where))
    if "$tuple" in value:
        items = value["$tuple"]
        if not isinstance(items, list):
            raise ValueError(f"{where}: $tuple must be a list")
        return tuple(decode_value(v, where) for v in items)
    if "$dict" in value:
        return {k: decode_value(v, where) for k, v in _mapping(value["$dict"], where).items()}
    raise ValueError(f"{where}: unknown encoded value {sorted(value)[:8]!r}")


def decode_fields(fields: dict[str, Any], where: str = "a logged message") -> dict[str, Any]:
    return {name: decode_value(v, f"{where}.{name}") for name, v in _mapping(fields, where).items()}
