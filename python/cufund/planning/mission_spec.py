"""LTLf missions over named regions: ``MissionSpec.parse("F(gate1 & F(gate2 & F(landing))) & G(!no_fly)")``.

A mission is a formula of linear temporal logic on finite traces (LTLf) whose propositions are region
names: ``r`` holds while the vehicle is inside region ``r``. The formula is compiled to a deterministic
finite automaton (DFA) with ``ltlf2dfa`` (PyPI), which calls Debian's ``mona``. :meth:`MissionSpec.plan`
then searches the product of the DFA with the region graph: the vehicle starts at a point, flies to one
region's waypoint after another, and each flight contributes two letters to the trace, the empty set
while in transit (between regions it is in none) and the set of regions holding the waypoint on
arrival. Dijkstra over (DFA state, last region) with straight-line distances gives the shortest visit
order the DFA accepts. A plain sequence ``F(a & F(b & F(c)))`` (or :meth:`MissionSpec.sequence`) takes
a fast path that needs no solver: the regions in order.

The path planner, not this module, must keep transit paths out of regions the mission forbids (treat
them as obstacles); the product assumes transit touches no region.
"""

from __future__ import annotations

import heapq
import math
import re
import subprocess
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt

from cufund.core.config import ConfigError, from_dict

__all__ = ["MissionPlan", "MissionSpec", "Region"]


@dataclass(frozen=True)
class Region:
    """A named box or sphere in the world frame; its waypoint is where the vehicle goes to visit it."""

    name: str
    centre_W: tuple[float, float, float]
    """Centre [m]."""
    size: tuple[float, float, float] | None = None
    """Edge lengths (x, y, z) [m] of an axis-aligned box, or None for a sphere."""
    radius: float | None = None
    """Radius [m] of a sphere, or None for a box."""
    waypoint_W: tuple[float, float, float] | None = None
    """Where to fly to visit it [m]; the centre if None (must lie inside)."""

    def __post_init__(self) -> None:
        if (
            not isinstance(self.name, str)
            or not re.fullmatch(r"[a-z_][a-z0-9_]*", self.name)
            or self.name in ("true", "false", "last", "end")
        ):
            raise ConfigError(
                f"region name must be lower-case letters, digits and _ (not a keyword), got {self.name!r}"
            )
        object.__setattr__(self, "centre_W", _vec3(f"region {self.name} centre_W", self.centre_W))
        if (self.size is None) == (self.radius is None):
            raise ConfigError(f"region {self.name} needs exactly one of size (box) or radius (sphere)")
        if self.size is not None:
            s = _vec3(f"region {self.name} size", self.size)
            if min(s) <= 0:
                raise ConfigError(f"region {self.name} size must be > 0 [m] on every axis, got {s}")
            object.__setattr__(self, "size", s)
        else:
            if not (isinstance(self.radius, (int, float)) and math.isfinite(self.radius) and self.radius > 0):
                raise ConfigError(f"region {self.name} radius must be finite and > 0 [m], got {self.radius!r}")
            object.__setattr__(self, "radius", float(self.radius))
        wp = self.centre_W if self.waypoint_W is None else _vec3(f"region {self.name} waypoint_W", self.waypoint_W)
        object.__setattr__(self, "waypoint_W", wp)
        if not self.contains(wp):
            raise ConfigError(f"region {self.name} waypoint_W {wp} is not inside the region")

    @classmethod
    def from_dict(cls, name: str, data: Mapping) -> Region:
        """From a world YAML's ``regions:`` entry, e.g. ``gate1: {centre_W: [2, 0, 1], size: [0.5, 1, 1]}``
        or ``landing: {centre_W: [6, 0, 0.2], radius: 0.5, waypoint_W: [6, 0, 0.5]}``."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"region {name} must be a mapping (centre_W and size or radius), got {data!r}")
        return from_dict(cls, {"name": name, **dict(data)}, where=f"region {name}")

    def contains(self, p_W: npt.ArrayLike) -> bool:
        p = np.asarray(p_W, dtype=float) - self.centre_W
        if self.size is not None:
            return bool(np.all(np.abs(p) <= 0.5 * np.asarray(self.size)))
        assert self.radius is not None  # a region is a box (size) or a sphere (radius), checked at construction
        return bool(np.linalg.norm(p) <= self.radius)


@dataclass(frozen=True)
class MissionPlan:
    """The shortest visit order the mission accepts."""

    regions: tuple[str, ...]
    """Regions to fly to, in order."""
    waypoints_W: np.ndarray
    """(K, 3) their waypoints [m] (the start not included)."""
    length: float
    """Sum of straight-line distances from the start through the waypoints [m]."""


def _vec3(name: str, v: object) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ConfigError(f"{name} must be 3 finite numbers [m], got {v!r}")
    return (float(a[0]), float(a[1]), float(a[2]))


# --- the DFA ---------------------------------------------------------------------------------------
_TOKEN = re.compile(r"\s*(?:([A-Za-z_][A-Za-z0-9_]*)|(.))")


def _guard(text: str) -> object:
    """Parses a MONA/ltlf2dfa edge label (names, ~, &, |, parentheses, true, false) into a tree."""
    tokens = [m.group(1) or m.group(2) for m in _TOKEN.finditer(text) if (m.group(1) or m.group(2) or "").strip()]
    pos = 0

    def peek() -> str | None:
        return tokens[pos] if pos < len(tokens) else None

    def take() -> str:
        nonlocal pos
        pos += 1
        return tokens[pos - 1]

    def disj() -> object:
        node = conj()
        while peek() == "|":
            take()
            node = ("or", node, conj())
        return node

    def conj() -> object:
        node = unary()
        while peek() == "&":
            take()
            node = ("and", node, unary())
        return node

    def unary() -> object:
        t = take()
        if t in ("~", "!"):
            return ("not", unary())
        if t == "(":
            node = disj()
            if take() != ")":
                raise ValueError(f"unbalanced parentheses in DFA label {text!r}")
            return node
        if t == "true":
            return True
        if t == "false":
            return False
        return ("var", t)

    tree = disj()
    if pos != len(tokens):
        raise ValueError(f"cannot parse DFA label {text!r}")
    return tree


def _holds(tree: object, true_vars: frozenset[str]) -> bool:
    if isinstance(tree, bool):
        return tree
    op = tree[0]  # type: ignore[index]
    if op == "var":
        return tree[1] in true_vars  # type: ignore[index]
    if op == "not":
        return not _holds(tree[1], true_vars)  # type: ignore[index]
    if op == "and":
        return _holds(tree[1], true_vars) and _holds(tree[2], true_vars)  # type: ignore[index]
    return _holds(tree[1], true_vars) or _holds(tree[2], true_vars)  # type: ignore[index]


@dataclass(frozen=True)
class Dfa:
    """A DFA over sets of true propositions: states, the initial one, the accepting ones, guarded edges."""

    initial: int
    accepting: frozenset[int]
    edges: tuple[tuple[int, int, object], ...]
    """(from, to, guard) with guard a parsed label."""

    def step(self, state: int, letter: frozenset[str]) -> int:
        """The successor of ``state`` on the letter (the set of propositions that hold)."""
        for a, b, g in self.edges:
            if a == state and _holds(g, letter):
                return b
        raise RuntimeError(f"the DFA has no edge from state {state} on {sorted(letter)} (not complete)")

    def accepts(self, word: list[frozenset[str]]) -> bool:
        q = self.initial
        for letter in word:
            q = self.step(q, letter)
        return q in self.accepting

    @classmethod
    def from_dot(cls, dot: str) -> Dfa:
        accepting: set[int] = set()
        initial = None
        edges = []
        for line in dot.splitlines():
            line = line.strip()
            m = re.match(r"node \[shape = doublecircle\];(.*)$", line)
            if m:
                accepting |= {int(x) for x in re.findall(r"\d+", m.group(1))}
                continue
            m = re.match(r"init -> (\d+);", line)
            if m:
                initial = int(m.group(1))
                continue
            m = re.match(r'(\d+) -> (\d+) \[label="(.*)"\];', line)
            if m:
                edges.append((int(m.group(1)), int(m.group(2)), _guard(m.group(3))))
        if initial is None:
            raise ValueError("no initial state in the DFA")
        return cls(initial, frozenset(accepting), tuple(edges))


def compile_ltlf(formula: str) -> Dfa:
    """The DFA of an LTLf formula (ltlf2dfa's MONA program, run by Debian's ``mona`` in a temporary folder)."""
    try:
        from ltlf2dfa.ltlf2dfa import MonaProgram, output2dot
        from ltlf2dfa.parser.ltlf import LTLfParser
    except ImportError as e:  # pragma: no cover - a dependency of cufund
        raise ConfigError("LTLf missions need the ltlf2dfa package (pip install ltlf2dfa)") from e
    try:
        parsed = LTLfParser()(formula)
    except Exception as e:  # lark's parse errors
        raise ConfigError(f"cannot parse the LTLf formula {formula!r}: {str(e).splitlines()[0]}") from None
    program = MonaProgram(parsed).mona_program()
    with tempfile.TemporaryDirectory(prefix="cufund-mona-") as d:
        path = Path(d) / "mission.mona"
        path.write_text(program, encoding="utf-8")
        try:
            out = subprocess.run(
                ["mona", "-q", "-u", "-w", str(path)], capture_output=True, text=True, timeout=60, check=False
            )
        except FileNotFoundError:
            raise ConfigError("LTLf missions need Debian's mona (apt-get install mona, or make deps)") from None
    if out.returncode != 0 and "Formula is unsatisfiable" not in out.stdout:
        raise ConfigError(f"mona failed on {formula!r}: {(out.stderr or out.stdout).strip()[:300]}")
    return Dfa.from_dot(output2dot(out.stdout.strip()))


# --- the mission -----------------------------------------------------------------------------------
_SEQ = re.compile(r"^\s*F\s*\(\s*([a-z_][a-z0-9_]*)\s*(?:&\s*(F\s*\(.*\))\s*)?\)\s*$")


def _plain_sequence(formula: str) -> list[str] | None:
    """``F(a & F(b & F(c)))`` -> [a, b, c]; None for anything else."""
    out = []
    rest: str | None = formula
    while rest is not None:
        m = _SEQ.match(rest)
        if not m:
            return None
        out.append(m.group(1))
        rest = m.group(2)
    return out


class MissionSpec:
    """A mission over named regions: an LTLf formula (compiled to a DFA) or a plain sequence."""

    def __init__(self, formula: str, sequence: list[str] | None, dfa: Dfa | None) -> None:
        self.formula = formula
        self.sequence = None if sequence is None else tuple(sequence)
        """The regions in order when the mission is a plain sequence (no DFA needed)."""
        self.dfa = dfa
        if dfa is None:
            assert self.sequence is not None  # a mission without a DFA is a plain sequence
            self.propositions = frozenset(self.sequence)
        else:
            self.propositions = frozenset(_names(formula))

    @classmethod
    def parse(cls, formula: str) -> MissionSpec:
        """Compiles ``formula``; an unsatisfiable one raises :class:`ConfigError`."""
        if not isinstance(formula, str) or not formula.strip():
            raise ConfigError(f"formula must be a non-empty LTLf string, got {formula!r}")
        seq = _plain_sequence(formula)
        if seq is not None:
            return cls(formula, seq, None)
        dfa = compile_ltlf(formula)
        if not dfa.accepting:
            raise ConfigError(f"the mission {formula!r} is unsatisfiable: no finite trace meets it")
        return cls(formula, None, dfa)

    @classmethod
    def sequence_of(cls, regions: list[str]) -> MissionSpec:
        """Visit ``regions`` in order (the fast path, no solver)."""
        if not regions or not all(isinstance(r, str) for r in regions):
            raise ConfigError(f"regions must be a non-empty list of names, got {regions!r}")
        return cls(" & ".join(f"F({r})" for r in regions), list(regions), None)

    def plan(self, regions: Mapping[str, Region] | list[Region], start_W: npt.ArrayLike) -> MissionPlan:
        """The shortest visit order from ``start_W`` (3,) [m] that the mission accepts."""
        table = {r.name: r for r in regions} if not isinstance(regions, Mapping) else dict(regions)
        unknown = sorted(self.propositions - set(table))
        if unknown:
            raise ConfigError(f"the mission names unknown regions {unknown}; declared: {sorted(table)}")
        start = np.asarray(_vec3("start_W", start_W))
        if self.dfa is None:
            pts = np.array([table[r].waypoint_W for r in self.sequence])  # type: ignore[union-attr]
            length = float(np.sum(np.linalg.norm(np.diff(np.vstack([start, pts]), axis=0), axis=1)))
            return MissionPlan(self.sequence, pts, length)  # type: ignore[arg-type]
        return self._search(table, start)

    def _search(self, table: dict[str, Region], start: np.ndarray) -> MissionPlan:
        dfa = self.dfa
        assert dfa is not None
        names = sorted(table)
        wp = {n: np.asarray(table[n].waypoint_W) for n in names}
        letter = {n: frozenset(m for m in names if m in self.propositions and table[m].contains(wp[n])) for n in names}
        empty: frozenset[str] = frozenset()
        start_letter = frozenset(m for m in names if m in self.propositions and table[m].contains(start))
        q0 = dfa.step(dfa.initial, start_letter)
        # Dijkstra over (cost, dfa state, node); ties broken by the visit sequence's names.
        heap: list[tuple[float, tuple[str, ...], int]] = [(0.0, (), q0)]
        done: set[tuple[int, str]] = set()
        while heap:
            cost, seq, q = heapq.heappop(heap)
            node = seq[-1] if seq else ""
            if (q, node) in done:
                continue
            done.add((q, node))
            if q in dfa.accepting and seq:
                pts = np.array([wp[n] for n in seq])
                return MissionPlan(seq, pts, cost)
            here = wp[node] if seq else start
            for n in names:
                if n == node:
                    continue
                q2 = dfa.step(dfa.step(q, empty), letter[n])
                if (q2, n) not in done:
                    heapq.heappush(heap, (cost + float(np.linalg.norm(wp[n] - here)), seq + (n,), q2))
        raise ConfigError(f"no order of visits to the declared regions satisfies the mission {self.formula!r}")

    def __repr__(self) -> str:
        kind = "sequence" if self.dfa is None else f"DFA with {len({e[0] for e in self.dfa.edges})} states"
        return f"MissionSpec({self.formula!r}, {kind})"


def _names(formula: str) -> set[str]:
    keywords = {"F", "G", "X", "WX", "U", "R", "W", "M", "true", "false", "last", "end", "tt", "ff"}
    return {t for t in re.findall(r"[A-Za-z_][A-Za-z0-9_]*", formula) if t not in keywords}
