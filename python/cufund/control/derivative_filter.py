"""The low-passed derivative that the PID loops' D terms act on (PX4's derivative low-pass filters)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["LowPassDerivative"]


class LowPassDerivative:
    """Backward difference of a sampled vector signal through a first-order low-pass with cutoff ``cutoff_hz``
    (0: no filtering). The first sample gives a zero difference, so D does not kick at start-up."""

    def __init__(self, cutoff_hz: float, dim: int = 3) -> None:
        self.cutoff_hz = cutoff_hz
        self.dim = dim
        self.reset()

    def reset(self) -> None:
        self.value = np.zeros(self.dim)
        """The filtered derivative."""
        self._prev: np.ndarray | None = None

    def update(self, x: np.ndarray, dt: float) -> np.ndarray:
        """Takes the sample ``x`` that follows the previous one by ``dt`` [s]; returns the filtered derivative."""
        if self._prev is None:
            self._prev = x.copy()
        alpha = dt / (dt + 1.0 / (2.0 * math.pi * self.cutoff_hz)) if self.cutoff_hz > 0 else 1.0
        self.value += alpha * ((x - self._prev) / dt - self.value)
        self._prev = x.copy()
        return self.value
