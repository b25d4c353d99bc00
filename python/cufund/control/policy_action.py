"""How a policy's action in [-1, 1]^4 becomes a command, per action mode: the same formulas as cufund.envs'
(``EnvBatch::commands`` in cpp/envs/env_batch.cpp; the velocity mode calls its C++ ``velocity_command``), for the
``policy`` controller.

- ``rotor_speeds``: ``omega_i = omega_hover + a_i * span``, ``omega_hover = sqrt(m g / (4 k_f))``,
  ``span = min(omega_max - omega_hover, omega_hover - omega_min)`` [rad/s];
- ``thrust_rates``: collective thrust ``T = min(m g (1 + a_0), 4 k_f omega_max^2)`` [N] and body rates
  ``w_sp = a_1..3 * max_rate`` [rad/s], for the rate loop;
- ``velocity``: the velocity setpoint ``a_0..2 * max_speed`` [m/s] through ``acc = k_v (v_sp - v_W)`` (with
  ``acc_z`` + g, at least 0.2 g), ``T = clamp(m acc . z_B, 0, T_max)``, roll/pitch rates
  ``k_att * (R_WB^T (z_B x acc / |acc|))_xy`` and yaw rate ``a_3 * max_rate``, for the rate loop.
"""

from __future__ import annotations

import numpy as np

from cufund import _core
from cufund.vehicle.params import QuadrotorParams

from .policy_manifest import PolicyManifest

__all__ = ["ActionDecoder"]


class ActionDecoder:
    """Commands from actions for one vehicle (its nominal params) and one exported policy's manifest."""

    def __init__(self, params: QuadrotorParams, manifest: PolicyManifest) -> None:
        self.params = params
        self.action_mode = manifest.action_mode
        self.mass = float(params.mass)
        self.gravity = float(params.gravity)
        self.omega_hover = params.hover_rotor_speed
        self.omega_span = min(params.rotor_speed_max - self.omega_hover, self.omega_hover - params.rotor_speed_min)
        self.max_thrust = params.max_thrust
        self.max_rate = manifest.max_rate
        self.max_speed = manifest.max_speed
        self.velocity_gain = manifest.velocity_gain
        self.attitude_gain = manifest.attitude_gain

    def rotor_speeds(self, a: np.ndarray) -> np.ndarray:
        """Rotor speed commands [rad/s] (4,)."""
        return self.omega_hover + np.asarray(a[:4], dtype=np.float64) * self.omega_span

    def thrust_rates(self, a: np.ndarray) -> tuple[float, np.ndarray]:
        """Collective thrust [N] and body-rate setpoint [rad/s] (3,)."""
        thrust = min(self.mass * self.gravity * (1.0 + float(a[0])), self.max_thrust)
        return thrust, np.asarray(a[1:4], dtype=np.float64) * self.max_rate

    def velocity(self, a: np.ndarray, v_W: np.ndarray, q_WB: np.ndarray) -> tuple[float, np.ndarray]:
        """Collective thrust [N] and body-rate setpoint [rad/s] (3,) tracking the velocity setpoint in ``a`` (the
        envs' own C++ formula, ``velocity_command`` in cpp/envs/env_batch.h)."""
        thrust, w = _core.envs.velocity_command(
            np.asarray(a[:4], dtype=np.float64).tolist(),
            np.asarray(v_W, dtype=np.float64).tolist(),
            np.asarray(q_WB, dtype=np.float64).tolist(),
            mass=self.mass,
            gravity=self.gravity,
            max_thrust=self.max_thrust,
            max_speed=self.max_speed,
            max_rate=self.max_rate,
            velocity_gain=self.velocity_gain,
            attitude_gain=self.attitude_gain,
        )
        return float(thrust), np.asarray(w, dtype=np.float64).reshape(3)
