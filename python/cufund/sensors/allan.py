"""Allan deviation of a sampled signal and a fit of the white-noise density and bias random walk."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["allan_deviation", "AllanFit", "fit_allan"]


def allan_deviation(y: np.ndarray, dt: float, taus: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping Allan deviation of rate samples ``y`` (K,) or (K, d) taken every ``dt`` [s].

    Returns ``(tau, adev)`` with tau [s] (M,) and adev (M,) or (M, d). Default taus: about 10 per decade
    from ``dt`` to a tenth of the record (clusters of m samples, m an integer; every power of ten of m
    is included, so tau = 1 s is when 1 / dt is one).
    """
    y = np.asarray(y, dtype=float)
    squeeze = y.ndim == 1
    y2 = y[:, None] if squeeze else y
    k = y2.shape[0]
    if k < 16:
        raise ValueError(f"y must have at least 16 samples, got {k}")
    if taus is None:
        m = np.unique(np.round(10.0 ** np.arange(0.0, np.log10(k / 10) + 1e-9, 0.1)).astype(int))
    else:
        m = np.unique(np.round(np.asarray(taus, dtype=float) / dt).astype(int))
        if m.min() < 1 or 2 * m.max() >= k:
            raise ValueError(f"taus must lie in [dt, record / 2] = [{dt}, {k * dt / 2}] s")
    theta = np.vstack([np.zeros((1, y2.shape[1])), np.cumsum(y2, axis=0) * dt])  # integrated signal
    adev = np.empty((len(m), y2.shape[1]))
    for i, mi in enumerate(m):
        tau = mi * dt
        d = theta[2 * mi :] - 2 * theta[mi:-mi] + theta[: -2 * mi]
        adev[i] = np.sqrt(np.mean(d * d, axis=0) / (2 * tau * tau))
    tau = m * dt
    return tau, (adev[:, 0] if squeeze else adev)


@dataclass(frozen=True)
class AllanFit:
    """White-noise density N [unit/sqrt(Hz)] and bias random walk K [unit/s/sqrt(Hz)] of one axis."""

    white_noise_density: float
    bias_random_walk: float


def fit_allan(tau: np.ndarray, adev: np.ndarray, record_s: float | None = None) -> AllanFit:
    """Least-squares fit of sigma^2(tau) = N^2 / tau + K^2 tau / 3, the IEEE 952 model without quantisation,
    bias-instability or rate-ramp terms, in relative terms. With ``record_s`` (the record length [s]) each
    tau is weighted by its number of independent clusters, record_s / tau, whose inverse square root is the
    relative uncertainty of that Allan variance; without it, every tau counts alike."""
    tau = np.asarray(tau, float)
    var = np.asarray(adev, float) ** 2
    weight = np.ones_like(tau) if record_s is None else np.sqrt(record_s / tau)
    basis = np.stack([1.0 / tau, tau / 3.0], axis=1) / var[:, None] * weight[:, None]
    coef, *_ = np.linalg.lstsq(basis, weight, rcond=None)
    n2, k2 = np.maximum(coef, 0.0)
    return AllanFit(float(np.sqrt(n2)), float(np.sqrt(k2)))
