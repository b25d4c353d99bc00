"""The paper's sensor error model (§2.2): white noise + bias random walk + constant (turn-on) bias.

For one channel sampled every ``dt`` seconds, with continuous-time densities in Kalibr's convention:

    y_k = x_k + b_0 + b_k + n_k,   n_k ~ N(0, sigma_w^2 / dt),   b_{k+1} = b_k + N(0, sigma_b^2 dt)

where ``sigma_w`` is the white-noise density [unit/sqrt(Hz)] and ``sigma_b`` the bias random walk
[unit/s/sqrt(Hz)] — the two lines of an Allan-deviation plot, ``sigma_w / sqrt(tau)`` (read at tau = 1 s)
and ``sigma_b * sqrt(tau / 3)``. ``b_0 ~ N(0, sigma_0^2)`` is drawn once per run (turn-on bias).

Random numbers come from one seeded ``numpy.random.Generator`` per process and are drawn in a fixed order
per sample, so a record is the same whether it is produced one sample at a time or in one call.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cufund.core.config import ConfigError, real_number


def real_fields(obj: object, where: str) -> None:
    """Every field of the frozen dataclass ``obj`` annotated ``float`` must hold a real number (not a bool,
    None, string or list); else a ConfigError naming ``where.field``. Ranges are the caller's checks."""
    import dataclasses

    for f in dataclasses.fields(obj):  # type: ignore[arg-type]
        if f.type in ("float", float):
            object.__setattr__(obj, f.name, real_number(f"{where}.{f.name}", getattr(obj, f.name)))


__all__ = ["ErrorProcess", "NoiseSpec"]


def _nonneg_vector(name: str, value: Any, dim: int) -> tuple[float, ...]:
    try:
        a = np.broadcast_to(np.asarray(value, dtype=float), (dim,)) if np.ndim(value) == 0 else np.asarray(value, float)
    except (TypeError, ValueError, OverflowError):
        a = np.full(1, np.nan)  # reported below
    if a.shape != (dim,) or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ConfigError(f"{name} must be a finite number >= 0 or {dim} of them, got {value!r}")
    return tuple(float(x) for x in a)


@dataclass(frozen=True)
class NoiseSpec:
    """Error densities of one sensor quantity (per axis, or one number for all axes)."""

    white_noise_density: float | tuple[float, ...] = 0.0
    """sigma_w [unit/sqrt(Hz)] (e.g. rad/s/sqrt(Hz) for a gyroscope, Kalibr's *_noise_density)."""
    bias_random_walk: float | tuple[float, ...] = 0.0
    """sigma_b [unit/s/sqrt(Hz)] (e.g. rad/s^2/sqrt(Hz), Kalibr's *_random_walk)."""
    turn_on_bias: float | tuple[float, ...] = 0.0
    """Standard deviation of the constant bias drawn at the start of each run [unit]."""

    def per_axis(self, dim: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return (
            np.array(_nonneg_vector("white_noise_density", self.white_noise_density, dim)),
            np.array(_nonneg_vector("bias_random_walk", self.bias_random_walk, dim)),
            np.array(_nonneg_vector("turn_on_bias", self.turn_on_bias, dim)),
        )


class ErrorProcess:
    """Generates the additive error of several channels that share one sample clock and one seed.

    ``specs`` lists (NoiseSpec, dim) groups, e.g. accelerometer (3) then gyroscope (3). Each sample draws,
    in order, the white noise of every channel and then the random-walk increments of every channel.
    """

    _BLOCK = 1024

    def __init__(self, specs: list[tuple[NoiseSpec, int]], dt: float, seed: int) -> None:
        if not (np.isfinite(dt) and dt > 0):
            raise ConfigError(f"sample period must be a finite number > 0 [s], got {dt!r}")
        parts = [spec.per_axis(dim) for spec, dim in specs]
        self.dim = sum(dim for _, dim in specs)
        self.dt = float(dt)
        self._sigma_white = np.concatenate([p[0] for p in parts]) / np.sqrt(dt)
        self._sigma_walk = np.concatenate([p[1] for p in parts]) * np.sqrt(dt)
        self._sigma_turn_on = np.concatenate([p[2] for p in parts])
        self.seed = seed
        self.reset()

    def reset(self) -> None:
        """Restarts the stream: new turn-on bias, random walk at zero, same seed -> same record."""
        self._rng = np.random.default_rng(self.seed)
        self.turn_on_bias = self._sigma_turn_on * self._rng.standard_normal(self.dim)
        self._walk_end = np.zeros(self.dim)  # the walk after the last computed sample
        self._errors = np.empty((0, self.dim))  # computed but not yet handed out
        self._walks = np.empty((0, self.dim))
        self._rows: list[list[float]] | None = None  # _errors as Python floats, made on first sample_one_values
        self._used = 0
        self._bias_row = -1  # the row of _walks of the last sample handed out (-1: none since reset)

    @property
    def bias(self) -> np.ndarray:
        """The random-walk part of the bias of the last sample handed out (zero before any)."""
        return self._walks[self._bias_row].copy() if self._bias_row >= 0 else np.zeros(self.dim)

    def _compute(self, k: int) -> None:
        """Computes the next ``k`` samples' errors into the buffer."""
        z = self._rng.standard_normal((k, 2 * self.dim))
        white = z[:, : self.dim] * self._sigma_white
        # Sample i uses the walk before increment i (zero at reset). Summing from the carried walk keeps the
        # left-to-right order of one-at-a-time sampling, so block sizes do not change a single bit.
        walk = np.cumsum(np.vstack([self._walk_end, z[:, self.dim :] * self._sigma_walk]), axis=0)
        self._walk_end = walk[-1].copy()
        self._walks = walk[:-1]
        self._errors = self.turn_on_bias + self._walks + white
        self._rows = None
        self._used = 0

    def sample(self, k: int = 1) -> np.ndarray:
        """The errors of the next ``k`` samples, shape (k, dim): turn-on bias + walk + white noise."""
        if self._used == len(self._errors) and k >= self._BLOCK:
            self._compute(k)
        parts = []
        need = k
        while need > 0:
            if self._used == len(self._errors):
                self._compute(self._BLOCK)
            take = min(need, len(self._errors) - self._used)
            parts.append(self._errors[self._used : self._used + take])
            self._used += take
            self._bias_row = self._used - 1
            need -= take
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def sample_one(self) -> np.ndarray:
        """The next sample's errors, shape (dim,) (a read-only view; cheap)."""
        if self._used == len(self._errors):
            self._compute(self._BLOCK)
        row = self._errors[self._used]
        self._bias_row = self._used
        self._used += 1
        return row

    def sample_one_values(self) -> list[float]:
        """:meth:`sample_one` as a list of ``dim`` Python floats (the same numbers, bit for bit; the buffer is
        converted once per block, so a per-sample caller does no numpy indexing). Do not modify it."""
        if self._used == len(self._errors):
            self._compute(self._BLOCK)
        rows = self._rows
        if rows is None:
            rows = self._rows = self._errors.tolist()
        i = self._used
        self._bias_row = i
        self._used = i + 1
        return rows[i]
