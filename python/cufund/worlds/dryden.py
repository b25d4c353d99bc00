"""Dryden turbulence: the model's scales and power spectral densities (MIL-F-8785C, low altitude).

MIL-F-8785C (1980) §3.7.2 and MIL-HDBK-1797 (1997) Appendix A give, below 1000 ft, with ``h`` in feet clamped to
[10, 1000] ft and ``W20`` the wind speed at 20 ft:

    sigma_w = 0.1 W20,   sigma_u = sigma_v = sigma_w / (0.177 + 0.000823 h)^0.4
    L_w = h,             L_u = L_v = h / (0.177 + 0.000823 h)^1.2

and the one-sided PSDs in temporal frequency omega [rad/s] at airspeed V (Taylor's frozen field, omega = V Omega):

    Phi_u(omega) = sigma_u^2 (2 L_u / (pi V)) / (1 + (L_u omega / V)^2)
    Phi_v(omega) = sigma_v^2 (L_v / (pi V)) (1 + 3 (L_v omega / V)^2) / (1 + (L_v omega / V)^2)^2   (w: L_w, sigma_w)

each integrating to sigma^2 over omega in [0, inf). u lies along the mean wind, v across it (horizontal), w up.
The generator (``cpp/dynamics/atmosphere.cpp``) shapes seeded white noise with the matching filters, stepped
exactly at each atmosphere update; this module holds the model for checks and plots.
"""

from __future__ import annotations

import numpy as np

from cufund import _core

__all__ = ["dryden_psd", "dryden_scales"]


def dryden_scales(h_m: float, wind_20ft_mps: float) -> dict[str, float]:
    """``sigma_u, sigma_v, sigma_w`` [m/s] and ``L_u, L_v, L_w`` [m] at height ``h_m`` [m] (the plant's values)."""
    return dict(_core.dynamics.dryden_scales(float(h_m), float(wind_20ft_mps)))


def dryden_psd(axis: str, omega: np.ndarray, sigma: float, L: float, V: float) -> np.ndarray:
    """One-sided PSD [(m/s)^2 / (rad/s)] of turbulence component ``axis`` ('u', 'v' or 'w') at ``omega`` [rad/s]."""
    x = L * np.asarray(omega, dtype=float) / V
    if axis == "u":
        return sigma**2 * 2.0 * L / (np.pi * V) / (1.0 + x**2)
    if axis in ("v", "w"):
        return sigma**2 * L / (np.pi * V) * (1.0 + 3.0 * x**2) / (1.0 + x**2) ** 2
    raise ValueError(f"axis must be 'u', 'v' or 'w', got {axis!r}")
