"""The interface planners query: a Euclidean (signed) distance field over the world."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt


@runtime_checkable
class DistanceField(Protocol):
    """Distance [m] from world points to the nearest obstacle, negative inside obstacles if signed."""

    def distance(self, p_W: npt.ArrayLike) -> np.ndarray:
        """Distances at points ``p_W`` (N, 3) [m] -> (N,) [m]."""
        ...

    def distance_and_gradient(self, p_W: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """Distances (N,) [m] and their gradients (N, 3) [m/m] at points ``p_W`` (N, 3) [m]."""
        ...
