"""Fixed-size CDR messages: their byte layout, as a numpy structured dtype with explicit offsets.

A message whose fields are all numbers and fixed-shape numeric arrays has the same CDR byte layout every time:
the 4-byte encapsulation header (little-endian CDR), then each field aligned to its own size, counted from the end
of the header (OMG CDR; what ROS 2 writes). The logger's compiled hot path (:class:`cufund._core.logs.LogCore`)
copies each message's fields straight to their offsets in a row (:meth:`MessageLayout.row_spec`); the checked
path (:meth:`MessageLayout.row`) and the reader (:meth:`MessageLayout.decode`) use the same dtype. Constant strings (the ``frame_id`` of a Foxglove schema on one topic) have a fixed length too and sit in the
template every row is copied from.

The ros2msg text of each layout is what Foxglove Studio and ``mcap-ros2-support`` decode the bytes with.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from dataclasses import dataclass
from operator import attrgetter, itemgetter
from typing import Any

import numpy as np

__all__ = ["CdrField", "CdrLayout", "MessageLayout", "infer_message_layout", "stamp_sec_nsec", "stamp_sec_nsec_of"]

CDR_LE_HEADER = b"\x00\x01\x00\x00"
_ROS_TYPES = {
    "f8": "float64",
    "f4": "float32",
    "i8": "int64",
    "i4": "int32",
    "i2": "int16",
    "i1": "int8",
    "u8": "uint64",
    "u4": "uint32",
    "u2": "uint16",
    "u1": "uint8",
    "b1": "bool",
}

OPTIONAL_ARRAY_SHAPES: dict[tuple[str, str], tuple[int, ...]] = {
    ("Odometry", "a_W"): (3,),
    ("Odometry", "alpha_B"): (3,),
    ("Odometry", "rotor_speeds"): (4,),
}
"""Shapes of optional array fields of cufund messages, so that a topic whose first message has ``None`` there
still gets a fixed layout."""

KEPT_WHEN_FIRST_SET: frozenset[tuple[str, str]] = frozenset({("Odometry", "pose_cov_W"), ("Odometry", "twist_cov_B")})
"""Optional array fields of cufund messages that a topic's rows hold only when its first message sets them: an
estimate's covariances (an estimator gives them from its first output or never; the truth, logged at every physics
step, does not carry 576 bytes of nothing per row). Set later on a topic whose first message had None: a
ValueError naming the field."""


@dataclass(frozen=True)
class CdrField:
    """One primitive field (or fixed array of them) of a CDR layout, or a constant string."""

    name: str
    """Column name (dotted for nested Foxglove fields: ``timestamp.sec``)."""
    code: str
    """numpy code without byte order (``f8``, ``i4``, ``b1``, ...), or ``str`` for a constant string."""
    count: int = 0
    """0: a scalar; else the length of a fixed array."""
    const: str = ""
    """The value of a constant string."""
    value: float | None = None
    """A number every element of a numeric field holds in the template (a sequence's length, a covariance's -1)."""


class CdrLayout:
    """Byte layout of one fixed-size CDR message: a numpy dtype with explicit offsets and a row template."""

    def __init__(self, fields: list[CdrField]):
        names, offsets = ["_header"], [0]
        formats: list[Any] = ["V4"]
        consts: list[tuple[str, bytes]] = []
        pos = 0  # relative to the end of the encapsulation header (CDR alignment origin)
        for f in fields:
            if f.code == "str":
                pos = _align(pos, 4)
                raw = f.const.encode() + b"\0"
                names += [f"_{f.name}.len", f"_{f.name}"]
                formats += ["<u4", f"V{len(raw)}"]
                offsets += [4 + pos, 4 + pos + 4]
                consts.append((f.name, raw))
                pos += 4 + len(raw)
                continue
            size = np.dtype(f.code).itemsize
            pos = _align(pos, size)
            names.append(f.name)
            formats.append((f"<{f.code}", (f.count,)) if f.count else f"<{f.code}")
            offsets.append(4 + pos)
            pos += size * max(f.count, 1)
        self.fields = fields
        self.dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": 4 + pos})
        self.size = 4 + pos
        template = np.zeros(1, self.dtype)
        template["_header"] = np.frombuffer(CDR_LE_HEADER, "V4")[0]
        for name, raw in consts:
            template[f"_{name}.len"] = len(raw)
            template[f"_{name}"] = np.frombuffer(raw, f"V{len(raw)}")[0]
        for f in fields:
            if f.value is not None and f.code != "str":
                if f.count:
                    template[f.name][0, 0] = f.value  # the first element (a covariance's "not provided")
                else:
                    template[f.name] = f.value
        self.template = template

    def empty(self, n: int) -> np.ndarray:
        """``n`` rows with the header and constant strings set, numbers zero."""
        return np.repeat(self.template, n)

    def ros2msg(self) -> str:
        """The field lines of the ros2msg definition (flat layouts only)."""
        lines = []
        for f in self.fields:
            if f.code == "str":
                lines.append(f"string {f.name}")
            else:
                lines.append(f"{_ROS_TYPES[f.code]}{f'[{f.count}]' if f.count else ''} {f.name}")
        return "\n".join(lines) + "\n"


def _align(pos: int, size: int) -> int:
    return (pos + size - 1) // size * size


def stamp_sec_nsec(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Seconds and nanoseconds of stamps ``t`` [s] (a ROS ``builtin_interfaces/Time``), rounded to 1 ns."""
    ns = np.round(np.asarray(t, dtype=np.float64) * 1e9)
    ns = np.nan_to_num(ns, nan=0.0, posinf=0.0, neginf=0.0).astype(np.int64)
    sec = np.floor_divide(ns, 1_000_000_000)
    return np.clip(sec, -(2**31), 2**31 - 1).astype(np.int32), (ns - sec * 1_000_000_000).astype(np.uint32)


def stamp_sec_nsec_of(t: float) -> tuple[int, int]:
    """:func:`stamp_sec_nsec` of one stamp ``t`` [s] in plain Python (~20x faster than through a 1-element array):
    the same float product and round-half-even, NaN and infinities 0, seconds clipped to int32."""
    ns_f = float(t) * 1e9
    if ns_f != ns_f or ns_f in (math.inf, -math.inf):
        return 0, 0
    sec, nsec = divmod(round(ns_f), 1_000_000_000)
    return min(max(sec, -(2**31)), 2**31 - 1), nsec


@dataclass(frozen=True)
class _Column:
    attr: str
    ros_name: str
    code: str
    shape: tuple[int, ...]
    optional: bool


class MessageLayout:
    """Exact CDR encoding of one dataclass whose fields are numbers and fixed-shape numeric arrays.

    Field names are lower-cased for the ros2msg schema (ROS 2 field names are lower case); an optional array
    field adds a ``bool has_<name>`` at the end. Arrays of more than one dimension are flattened; their shape
    and dtype travel in the channel metadata (:meth:`describe`)."""

    def __init__(self, cls: type, columns: list[_Column]):
        self.cls = cls
        self.columns = columns
        fields = [CdrField(c.ros_name, c.code, int(np.prod(c.shape)) if c.shape else 0) for c in columns]
        fields += [CdrField(f"has_{c.ros_name}", "b1") for c in columns if c.optional]
        self.layout = CdrLayout(fields)
        kept = {c.attr for c in columns}
        self.left_out = tuple(a for c, a in sorted(KEPT_WHEN_FIRST_SET) if c == cls.__name__ and a not in kept)
        """:data:`KEPT_WHEN_FIRST_SET` fields the topic's rows have no room for (None in its first message)."""
        self._columns = [itemgetter(i) for i in range(len(columns))]
        self._all = _getter([c.attr for c in columns])

    def row_spec(
        self, first: Any
    ) -> tuple[bytes, list[tuple[str, str, int]], list[tuple[str, np.dtype, int, int]], list[str]]:
        """How :class:`cufund._core.logs.LogCore` packs a message like ``first`` (the same optional arrays present)
        straight into a CDR row: (template row, scalars (attribute, struct code, offset), arrays (attribute, dtype,
        bytes, offset), attributes that must be None). Any other message takes :meth:`row`."""
        fields = self.layout.dtype.fields
        assert fields is not None  # a structured dtype
        template = self.layout.empty(1)
        scalars, arrays, absent = [], [], list(self.left_out)
        for c in self.columns:
            if not c.shape:
                scalars.append((c.attr, _STRUCT_CODES[c.code], fields[c.ros_name][1]))
            elif getattr(first, c.attr) is None:
                absent.append(c.attr)
            else:
                dtype = np.dtype(c.code)
                arrays.append((c.attr, dtype, int(np.prod(c.shape)) * dtype.itemsize, fields[c.ros_name][1]))
                if c.optional:
                    template[f"has_{c.ros_name}"] = True
        return template.tobytes(), scalars, arrays, absent

    def row(self, message: Any, topic: str) -> bytes:
        """The checked path: one message's CDR row (ValueError naming the field when a shape or dtype differs
        from the topic's first message)."""
        for attr in self.left_out:
            if getattr(message, attr, None) is not None:
                raise ValueError(
                    f"topic {topic!r}: field {attr!r} is set but was None in the topic's first message, so the log "
                    "has no room for it: set it from a topic's first message on, or never"
                )
        return self._rows([self._all(message)], topic).tobytes()

    def describe(self) -> list[list[Any]]:
        """The columns as JSON-able lists (kept in the channel metadata; :meth:`from_description` inverts it)."""
        return [[c.attr, c.ros_name, c.code, list(c.shape), c.optional] for c in self.columns]

    @classmethod
    def from_description(cls, message_cls: type, description: list[list[Any]]) -> MessageLayout:
        """Inverse of :meth:`describe`; ValueError when the description (read from a file) is not one: fields of
        ``message_cls``, numeric codes, shapes of at most 2**24 elements."""
        names = {f.name for f in dataclasses.fields(message_cls)}
        if not isinstance(description, list) or len(description) > len(names):
            raise ValueError(f"the CDR layout of {message_cls.__name__} must list at most its {len(names)} fields")
        columns = []
        for item in description:
            if not (isinstance(item, list) and len(item) == 5):
                raise ValueError(f"a CDR layout column must be [attr, name, code, shape, optional], got {item!r}")
            a, r, code, shape, opt = item
            if a not in names or not isinstance(r, str) or not r.isidentifier() or code not in _ROS_TYPES:
                raise ValueError(
                    f"a CDR layout column of {message_cls.__name__} names an unknown field or type: {item!r}"
                )
            if not (
                isinstance(shape, list)
                and len(shape) <= 4
                and all(isinstance(n, int) and not isinstance(n, bool) and 1 <= n <= 2**24 for n in shape)
                and math.prod(shape) <= 2**24
            ):
                raise ValueError(f"a CDR layout column of {message_cls.__name__} has a bad shape: {item!r}")
            columns.append(_Column(a, r, code, tuple(shape), bool(opt)))
        if len({c.ros_name for c in columns}) != len(columns):
            raise ValueError(f"the CDR layout of {message_cls.__name__} repeats a field")
        return cls(message_cls, columns)

    def _rows(self, values_of: list[tuple[Any, ...]], topic: str) -> np.ndarray:
        """The general path: rows from every field value of each message (validates shapes and dtypes)."""
        n = len(values_of)
        rows = self.layout.empty(n)
        for col, get in zip(self.columns, self._columns, strict=True):
            values = list(map(get, values_of))
            if not col.shape:
                rows[col.ros_name] = np.array(values, dtype=col.code)
                continue
            if col.optional:
                present = [v is not None for v in values]
                rows[f"has_{col.ros_name}"] = present
                if not all(present):
                    index = [i for i, p in enumerate(present) if p]
                    if index:
                        rows[col.ros_name][index] = self._stack([values[i] for i in index], col, topic)
                    continue
            rows[col.ros_name] = self._stack(values, col, topic)
        return rows

    @staticmethod
    def _stack(values: list[Any], col: _Column, topic: str) -> np.ndarray:
        """(n, count) array of one array column (ValueError naming the field when a shape or dtype differs from
        the topic's first message)."""
        n, dtype = len(values), np.dtype(col.code)
        try:
            block = np.array(values)
        except ValueError as exc:  # ragged
            raise ValueError(
                f"topic {topic!r}: field {col.attr!r} changed shape within the log (expected {col.shape})"
            ) from exc
        if block.shape[1:] != col.shape:
            raise ValueError(
                f"topic {topic!r}: field {col.attr!r} has shape {block.shape[1:]}, "
                f"the topic's first message had {col.shape}"
            )
        if not np.can_cast(block.dtype, dtype, casting="same_kind"):
            raise ValueError(
                f"topic {topic!r}: field {col.attr!r} has dtype {block.dtype}, the topic's first message had {dtype}"
            )
        return block.reshape(n, -1)

    def decode(self, data: bytes | memoryview) -> Any:
        if len(data) != self.layout.size:
            raise ValueError(f"a {self.cls.__name__} record has {len(data)} bytes, the schema needs {self.layout.size}")
        row = np.frombuffer(data, self.layout.dtype, count=1)[0]
        kwargs: dict[str, Any] = {}
        for col in self.columns:
            value = row[col.ros_name]
            if col.optional and not row[f"has_{col.ros_name}"]:
                kwargs[col.attr] = None
            elif col.shape:
                kwargs[col.attr] = np.array(value, dtype=np.dtype(col.code)).reshape(col.shape)
            elif col.code == "f8":
                kwargs[col.attr] = float(value)
            elif col.code == "b1":
                kwargs[col.attr] = bool(value)
            else:
                kwargs[col.attr] = int(value)
        return self.cls(**kwargs)


def _getter(attrs: list[str]) -> Any:
    """``attrgetter`` that always returns a tuple (also of one or no attribute)."""
    if not attrs:
        return lambda message: ()
    if len(attrs) == 1:
        get = attrgetter(attrs[0])
        return lambda message: (get(message),)
    return attrgetter(*attrs)


_STRUCT_CODES = {"f8": "d", "i8": "q", "b1": "?"}


def _unwrap_optional(hint: Any) -> tuple[Any, bool]:
    if typing.get_origin(hint) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if len(args) == 1 and len(typing.get_args(hint)) == 2:
            return args[0], True
        return None, False
    return hint, False


def infer_message_layout(cls: type, first: Any) -> MessageLayout | None:
    """The fixed CDR layout of dataclass ``cls``, from its type hints and its ``first`` message (array shapes and
    dtypes); None when a field is not a number or a numeric array (the JSON codec takes those)."""
    if not dataclasses.is_dataclass(cls) or getattr(cls, "variable_length", False):
        return None  # variable_length: a message class whose array sizes change from message to message
    try:
        hints = typing.get_type_hints(cls)
    except Exception:
        return None
    columns = []
    for field in dataclasses.fields(cls):
        base, optional = _unwrap_optional(hints.get(field.name))
        ros_name = field.name.lower()
        if base is float and not optional:
            columns.append(_Column(field.name, ros_name, "f8", (), False))
        elif base is bool and not optional:
            columns.append(_Column(field.name, ros_name, "b1", (), False))
        elif base is int and not optional:
            columns.append(_Column(field.name, ros_name, "i8", (), False))
        elif base is np.ndarray:
            value = getattr(first, field.name, None)
            if value is None and optional and (cls.__name__, field.name) in KEPT_WHEN_FIRST_SET:
                continue  # no room in this topic's rows (see KEPT_WHEN_FIRST_SET)
            if value is not None:
                shape = tuple(value.shape) if isinstance(value, np.ndarray) else None
            else:
                shape = OPTIONAL_ARRAY_SHAPES.get((cls.__name__, field.name))
            if value is not None:
                if not isinstance(value, np.ndarray) or value.dtype.kind not in "fiub" or value.size == 0:
                    return None
                code = "b1" if value.dtype.kind == "b" else value.dtype.str[1:]
            else:
                code = "f8"
            if shape is None or len(shape) == 0 or code not in _ROS_TYPES:
                return None
            columns.append(_Column(field.name, ros_name, code, shape, optional))
        else:
            return None
    names = [c.ros_name for c in columns]
    if len(set(names)) != len(names):
        return None
    return MessageLayout(cls, columns)
