"""Loading typed, frozen configuration dataclasses from plain dicts and YAML, with clear errors."""

from __future__ import annotations

import dataclasses
import math
import numbers
import re
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import yaml

from .errors import ConfigError as ConfigError  # re-exported: ConfigError was defined here in 0.1
from .limits import current

T = TypeVar("T")


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
    required = [
        f.name
        for f in dataclasses.fields(cls)  # type: ignore[arg-type]
        if f.init and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
    ]
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


def check_real_fields(
    obj: Any, where: str, positive: bool = False, unit: str = "", names: tuple[str, ...] | None = None
) -> None:
    """Makes the fields ``names`` (default: every field) of the frozen dataclass ``obj`` floats, requiring a
    finite number >= 0 (> 0 when ``positive``); the error names ``where.field``."""
    bound = "> 0" if positive else ">= 0"
    for name in names if names is not None else [f.name for f in dataclasses.fields(obj)]:
        v = getattr(obj, name)
        if (
            isinstance(v, bool)
            or not isinstance(v, (int, float))
            or not math.isfinite(v)
            or v < 0
            or (positive and v == 0)
        ):
            raise ConfigError(f"{where}.{name} must be a finite number {bound}{unit}, got {v!r}")
        object.__setattr__(obj, name, float(v))


def check_at_most(obj: Any, where: str, **bounds: float) -> None:
    """Upper bounds on fields of ``obj`` (field name = its bound; numbers already checked finite): a rate or size
    past its bound is a ConfigError naming ``where.field``, the bound and the value, before anything is built (a
    1e9 Hz sensor would otherwise fill the disk with its log)."""
    for name, bound in bounds.items():
        v = getattr(obj, name)
        if isinstance(v, (int, float)) and not isinstance(v, bool) and v > bound:
            raise ConfigError(f"{where}.{name} must be at most {bound:g}, got {v!r}")


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


class DuplicateKeyError(yaml.YAMLError):
    """A mapping that gives the same key twice (PyYAML keeps the last value silently: ``hover_s:`` written twice
    flew the second one with no word)."""

    def __init__(self, key: Any, line: int, first_line: int) -> None:
        super().__init__(f"duplicate key {key!r} at line {line} (first given at line {first_line})")
        self.key, self.line, self.first_line = key, line, first_line


class CufundLoader(yaml.SafeLoader):
    """PyYAML's safe loader (plain data only: no ``!!python`` tags, nothing imported or called) that also reads
    YAML 1.2 numbers like ``1e9``, ``1e-3``, ``-2E5`` and ``1.5e3`` as floats (YAML 1.1 needs a dot and a signed
    exponent, so those were strings and a bound check said "got '1e9'"), and refuses a mapping that gives a key twice
    (:class:`DuplicateKeyError`, naming the key and both lines)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        """A mapping whose explicit keys are unique (a key that a merge ``<<: *anchor`` brings in may still be
        overridden, as YAML specifies)."""
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=True)
            try:
                first = seen.get(key)
            except TypeError:  # an unhashable key: PyYAML's own error follows
                continue
            if first is not None:
                raise DuplicateKeyError(key, key_node.start_mark.line + 1, first)
            seen[key] = key_node.start_mark.line + 1
        mapping: dict[Any, Any] = super().construct_mapping(node, deep=deep)
        return mapping


CufundLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9][0-9_]*)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def load_yaml(path: str | Path) -> Any:
    """Parses a YAML file with :class:`CufundLoader`; a syntax error names the file and line.

    Bounded (see :mod:`cufund.core.limits`): the file size, the nesting depth, alias uses and the size of the
    document with its aliases expanded, so that a "billion laughs" or self-referencing file fails fast
    with :class:`ConfigError` instead of filling the memory.
    """
    lim = current()
    path = Path(path)
    size = path.stat().st_size
    if size > lim.yaml_max_bytes:
        raise ConfigError(
            f"{path}: the file is {size} bytes, more than yaml_max_bytes = {lim.yaml_max_bytes} "
            "(cufund.core.limits.configure(yaml_max_bytes=...))"
        )
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(f"{path}: not UTF-8 text: {e}") from None
    return load_yaml_text(text, str(path))


def load_yaml_text(text: str, where: str) -> Any:
    """Parses YAML ``text`` (a ``--set`` value, the config a log records) as :func:`load_yaml` parses a file, with
    the same bounds; errors name ``where``."""
    lim = current()
    if len(text) > lim.yaml_max_bytes:
        raise ConfigError(f"{where}: {len(text)} characters of YAML, more than yaml_max_bytes = {lim.yaml_max_bytes}")
    try:
        node = yaml.compose(text, Loader=CufundLoader)
        if node is None:
            return None
        _check_yaml_graph(node, where, lim)
        return yaml.load(text, Loader=CufundLoader)  # CufundLoader is a SafeLoader
    except RecursionError:
        raise ConfigError(f"{where}: nesting deeper than yaml_max_depth = {lim.yaml_max_depth}") from None
    except DuplicateKeyError as e:
        field = _key_path(node, e.line, e.key) or repr(e.key)
        raise ConfigError(f"{where}: {e}: {field} may be given only once") from None
    except yaml.YAMLError as e:
        raise ConfigError(f"{where}: invalid YAML: {e}") from e


def _key_path(root: yaml.Node, line: int, key: Any) -> str | None:
    """The dotted path (``trajectory.hover_s``, ``grid.seed``, ``items[2].yaw``) of the mapping key ``key`` that
    starts on 1-based ``line`` of a composed document, or None."""
    stack: list[tuple[yaml.Node, str]] = [(root, "")]
    seen: set[int] = set()
    while stack:
        n, path = stack.pop()
        if id(n) in seen:
            continue
        seen.add(id(n))
        if isinstance(n, yaml.MappingNode):
            for k, v in n.value:
                name = f"{path}.{k.value}" if path else str(k.value)
                if isinstance(k, yaml.ScalarNode) and k.start_mark.line + 1 == line and k.value == str(key):
                    return name
                stack.append((v, name))
        elif isinstance(n, yaml.SequenceNode):
            stack.extend((v, f"{path}[{i}]") for i, v in enumerate(n.value))
    return None


def _check_yaml_graph(root: yaml.Node, path: Path | str, lim: Any) -> None:
    """Depth, alias uses, expanded size and cycles of a composed YAML node graph (an alias is the anchored
    node itself, reached a second time), walked iteratively in time linear in the distinct nodes."""

    def children(n: yaml.Node) -> list[yaml.Node]:
        if isinstance(n, yaml.MappingNode):
            return [x for kv in n.value for x in kv]
        if isinstance(n, yaml.SequenceNode):
            return list(n.value)
        return []

    where = f"{path}"
    done: dict[int, tuple[int, int]] = {}  # id -> (nodes with aliases expanded, depth)
    on_path: set[int] = set()
    aliases = 0
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        n, finished = stack.pop()
        key = id(n)
        if finished:
            on_path.discard(key)
            kids = children(n)
            size = 1 + sum(done[id(c)][0] for c in kids)
            depth = 1 + max((done[id(c)][1] for c in kids), default=0)
            if depth > lim.yaml_max_depth:
                raise ConfigError(
                    f"{where}: nesting deeper than yaml_max_depth = {lim.yaml_max_depth} (line {n.start_mark.line + 1})"
                )
            if size > lim.yaml_max_nodes:
                raise ConfigError(
                    f"{where}: more than yaml_max_nodes = {lim.yaml_max_nodes} values with aliases "
                    f"expanded (line {n.start_mark.line + 1}: a 'billion laughs' file?)"
                )
            done[key] = (size, depth)
            continue
        if key in done:
            aliases += 1
            if aliases > lim.yaml_max_aliases:
                raise ConfigError(f"{where}: more than yaml_max_aliases = {lim.yaml_max_aliases} alias uses")
            continue
        if key in on_path:
            raise ConfigError(f"{where}: an alias refers to a value that contains it (line {n.start_mark.line + 1})")
        on_path.add(key)
        stack.append((n, True))
        stack.extend((c, False) for c in children(n))


def to_dict(obj: Any) -> dict[str, Any]:
    """A dataclass as plain Python data (nested dataclasses become dicts, tuples lists) suitable for
    ``yaml.safe_dump``. A nested object with a ``to_data()`` method is written as what that returns (the form its
    parser reads back, e.g. a commander script's commands)."""

    def plain(x: Any) -> Any:
        to_data = getattr(x, "to_data", None)
        if callable(to_data) and not isinstance(x, type):
            return plain(to_data())
        if isinstance(x, dict):
            return {k: plain(v) for k, v in x.items()}
        if dataclasses.is_dataclass(x) and not isinstance(x, type):
            return {f.name: plain(getattr(x, f.name)) for f in dataclasses.fields(x)}
        if isinstance(x, (tuple, list)):
            return [plain(v) for v in x]
        return x

    return {f.name: plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
