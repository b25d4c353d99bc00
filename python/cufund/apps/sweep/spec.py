"""A sweep file and the variants it expands to.

```yaml
scenario: square                 # base scenario: a built-in name or a path (relative to the sweep file)
set: {duration: 20}              # optional: overrides applied to every variant
grid:                            # every combination of these dotted overrides
  controller.kind: [pid, geometric]
  seed: [3, 8]
random:                          # optional: n draws, seeded, each combined with every grid point
  n: 20
  seed: 0
  draws: {controller.position.xy_p: {uniform: [0.8, 1.2]}, world.seed: {range: [0, 200]}}
repeats: 1                       # repeat r > 0 runs with a seed derived from (seed, r)
```

Every variant is resolved (base scenario + ``set`` + its grid point + its draw) and validated, graph included,
before anything runs: a bad override fails the whole sweep with :class:`cufund.ConfigError` naming it. A variant
is keyed by a hash of its resolved configuration (what its ``config.yaml`` holds), which is what makes a sweep
resumable.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cufund.core.config import ConfigError, load_yaml
from cufund.scenarios.schema import ScenarioConfig, load_scenario, parse_overrides

__all__ = ["DISTRIBUTIONS", "SweepSpec", "Variant", "config_key", "load_spec"]

DISTRIBUTIONS = ("uniform", "loguniform", "normal", "range", "choice")
"""``uniform: [lo, hi]``, ``loguniform: [lo, hi]`` (lo > 0), ``normal: [mean, std]``, ``range: [lo, hi]`` (an
integer in [lo, hi), like Python's ``range``), ``choice: [a, b, ...]``."""

_KEYS = ("scenario", "set", "grid", "random", "repeats")
_MAX_VARIANTS = 1_000_000


@dataclass(frozen=True)
class Variant:
    """One run of a sweep."""

    index: int
    overrides: dict[str, Any]
    """The swept overrides of this variant (grid point and draws), by dotted key."""
    repeat: int
    config: ScenarioConfig
    key: str
    """Hash of the resolved configuration (see :func:`config_key`)."""


@dataclass(frozen=True)
class SweepSpec:
    """A parsed sweep file (see the module doc)."""

    scenario: str
    set: dict[str, Any] = field(default_factory=dict)
    grid: dict[str, list[Any]] = field(default_factory=dict)
    random_n: int = 0
    random_seed: int = 0
    draws: dict[str, tuple[str, list[Any]]] = field(default_factory=dict)
    repeats: int = 1
    base_dir: str | None = None
    """Where the sweep file lies: a relative ``scenario`` path resolves from there."""

    @property
    def swept_keys(self) -> list[str]:
        """The dotted keys that vary, in the order of the file: grid keys, then drawn keys."""
        return list(self.grid) + [k for k in self.draws if k not in self.grid]

    def variants(self, validate: bool = True) -> list[Variant]:
        """Every variant, resolved; with ``validate`` each one's whole graph is built (nothing runs), so a bad
        override raises :class:`ConfigError` naming the variant and the field before any work starts."""
        from cufund.scenarios.build import build_simulation

        base = self._base()
        n_grid = math.prod(len(v) for v in self.grid.values())
        total = n_grid * max(self.random_n, 1) * self.repeats
        if total > _MAX_VARIANTS:
            raise ConfigError(f"sweep: {total} variants, more than {_MAX_VARIANTS}; split the sweep")
        draws = self._draw()
        out: list[Variant] = []
        built: set[str] = set()  # identical configurations (equal draws, say) are validated once
        for point in itertools.product(*self.grid.values()):
            grid_point = dict(zip(self.grid, point, strict=True))
            for draw in draws:
                swept = {**grid_point, **draw}
                for r in range(self.repeats):
                    overrides = {**self.set, **swept}
                    where = ", ".join(f"{k}={v!r}" for k, v in swept.items()) or "the base scenario"
                    try:
                        cfg = base.with_overrides(overrides)
                        if r > 0:
                            cfg = cfg.with_overrides({"seed": repeat_seed(cfg.seed, r)})
                        key = config_key(cfg)
                        if validate and key not in built:
                            build_simulation(cfg)
                            built.add(key)
                    except ConfigError as e:
                        raise ConfigError(
                            f"sweep variant {where}" + (f" (repeat {r})" if r else "") + f": {e}"
                        ) from None
                    out.append(Variant(len(out), swept, r, cfg, key))
        return out

    def _base(self) -> ScenarioConfig:
        path = Path(self.scenario)
        if self.base_dir is not None and path.suffix and not path.is_absolute():
            path = Path(self.base_dir) / path
        try:
            return load_scenario(path if path.suffix else self.scenario, self.set)
        except ConfigError as e:
            raise ConfigError(
                f"sweep: scenario {self.scenario!r}" + (" with set" if self.set else "") + f": {e}"
            ) from None

    def _draw(self) -> list[dict[str, Any]]:
        if self.random_n == 0:
            return [{}]
        rng = np.random.default_rng(self.random_seed)
        out = []
        for _ in range(self.random_n):
            row = {}
            for key, (dist, args) in self.draws.items():
                row[key] = _sample(rng, dist, args)
            out.append(row)
        return out


def _sample(rng: np.random.Generator, dist: str, args: list[Any]) -> Any:
    if dist == "uniform":
        return float(rng.uniform(args[0], args[1]))
    if dist == "loguniform":
        return float(math.exp(rng.uniform(math.log(args[0]), math.log(args[1]))))
    if dist == "normal":
        return float(rng.normal(args[0], args[1]))
    if dist == "range":
        return int(rng.integers(args[0], args[1]))
    return args[int(rng.integers(0, len(args)))]  # choice


def repeat_seed(seed: int, repeat: int) -> int:
    """The scenario seed of repeat ``repeat`` (> 0) of a variant whose seed is ``seed``: independent streams that do
    not collide with a neighbouring seed of the grid (seed + 1 would)."""
    state = np.random.SeedSequence([int(seed), int(repeat)]).generate_state(2, dtype=np.uint32)
    return int((int(state[0]) << 31) ^ int(state[1])) % (2**63)


def config_key(config: ScenarioConfig) -> str:
    """A stable hash (16 hex digits of SHA-256) of the resolved configuration, as its ``config.yaml`` holds it."""
    text = json.dumps(config.to_dict(), sort_keys=True, separators=(",", ":"), default=repr)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def load_spec(spec: str | Path | Mapping[str, Any] | SweepSpec) -> SweepSpec:
    """A :class:`SweepSpec` from a YAML file, a mapping with the file's keys, or a spec (returned as is).
    Raises :class:`ConfigError` naming the key that is wrong."""
    if isinstance(spec, SweepSpec):
        return spec
    base_dir = None
    if isinstance(spec, (str, Path)):
        path = Path(spec)
        if not path.is_file():
            raise ConfigError(f"sweep file {str(spec)!r} does not exist")
        data = load_yaml(path)
        base_dir = str(path.resolve().parent)
        where = str(path)
    else:
        data, where = spec, "sweep"
    if not isinstance(data, Mapping):
        raise ConfigError(f"{where}: a sweep must be a mapping with keys {', '.join(_KEYS)}, got {type(data).__name__}")
    unknown = sorted(set(map(str, data)) - set(_KEYS))
    if unknown:
        raise ConfigError(f"unknown key {unknown[0]!r} in sweep; expected one of: {', '.join(_KEYS)}")
    scenario = data.get("scenario")
    if isinstance(scenario, Path):
        scenario = str(scenario)
    if not isinstance(scenario, str) or not scenario:
        raise ConfigError(f"sweep.scenario must be a scenario name or path, got {scenario!r}")
    base = data.get("set") or {}
    if isinstance(base, (list, tuple)):
        base = parse_overrides(base)
    if not isinstance(base, Mapping):
        raise ConfigError(f"sweep.set must be a mapping of dotted keys to values, got {type(base).__name__}")
    grid = data.get("grid") or {}
    if not isinstance(grid, Mapping):
        raise ConfigError(f"sweep.grid must be a mapping of dotted keys to lists of values, got {type(grid).__name__}")
    for key, values in grid.items():
        _check_key(key, "sweep.grid")
        if not isinstance(values, (list, tuple)) or not values:
            raise ConfigError(f"sweep.grid.{key} must be a non-empty list of values, got {values!r}")
    random_n, random_seed, draws = _parse_random(data.get("random"))
    repeats = data.get("repeats", 1)
    if isinstance(repeats, bool) or not isinstance(repeats, int) or not 1 <= repeats <= 10_000:
        raise ConfigError(f"sweep.repeats must be an integer in [1, 10000], got {repeats!r}")
    for key in base:
        _check_key(key, "sweep.set")
    return SweepSpec(
        scenario, dict(base), {k: list(v) for k, v in grid.items()}, random_n, random_seed, draws, repeats, base_dir
    )


def _check_key(key: Any, where: str) -> None:
    if not isinstance(key, str) or not key or any(not p for p in key.split(".")):
        raise ConfigError(f"{where}: a key must be a dotted name like controller.kind, got {key!r}")


def _parse_random(rnd: Any) -> tuple[int, int, dict[str, tuple[str, list[Any]]]]:
    if rnd is None:
        return 0, 0, {}
    if not isinstance(rnd, Mapping):
        raise ConfigError(f"sweep.random must be a mapping with n, seed and draws, got {type(rnd).__name__}")
    unknown = sorted(set(map(str, rnd)) - {"n", "seed", "draws"})
    if unknown:
        raise ConfigError(f"unknown key {unknown[0]!r} in sweep.random; expected one of: n, seed, draws")
    n, seed, draws = rnd.get("n"), rnd.get("seed", 0), rnd.get("draws")
    if isinstance(n, bool) or not isinstance(n, int) or not 1 <= n <= _MAX_VARIANTS:
        raise ConfigError(f"sweep.random.n must be an integer in [1, {_MAX_VARIANTS}], got {n!r}")
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63:
        raise ConfigError(f"sweep.random.seed must be an integer in [0, 2^63), got {seed!r}")
    if not isinstance(draws, Mapping) or not draws:
        raise ConfigError(
            "sweep.random.draws must be a non-empty mapping of dotted keys to distributions, e.g. "
            "{controller.position.xy_p: {uniform: [0.8, 1.2]}}"
        )
    out: dict[str, tuple[str, list[Any]]] = {}
    for key, d in draws.items():
        _check_key(key, "sweep.random.draws")
        where = f"sweep.random.draws.{key}"
        if not isinstance(d, Mapping) or len(d) != 1 or next(iter(d)) not in DISTRIBUTIONS:
            raise ConfigError(f"{where} must be one of {{{': [...]}, {'.join(DISTRIBUTIONS)}: [...]}}, got {d!r}")
        dist, args = next(iter(d.items()))
        out[key] = (dist, _check_args(dist, args, where))
    return n, seed, out


def _check_args(dist: str, args: Any, where: str) -> list[Any]:
    if not isinstance(args, (list, tuple)) or not args:
        raise ConfigError(f"{where}.{dist} must be a list, got {args!r}")
    if dist == "choice":
        return list(args)
    ok = len(args) == 2 and all(
        isinstance(a, (int, float)) and not isinstance(a, bool) and math.isfinite(a) for a in args
    )
    if dist == "range":
        ok = ok and all(isinstance(a, int) for a in args) and args[0] < args[1]
        expected = "two integers [lo, hi) with lo < hi"
    elif dist == "normal":
        ok = ok and args[1] >= 0
        expected = "[mean, std] with std >= 0"
    else:
        ok = ok and args[0] <= args[1] and (dist == "uniform" or args[0] > 0)
        expected = "[lo, hi] with lo <= hi" + (" and lo > 0" if dist == "loguniform" else "")
    if not ok:
        raise ConfigError(f"{where}.{dist} must be {expected}, got {args!r}")
    return list(args)
