"""The PX4-style cascade's arithmetic as it was written in Python and numpy before it moved to C++
(cpp/control/{position,attitude,rate}_control.cpp): the reference that tests/control/test_control_kernels.py holds the C++
loops to, bit for bit, on random inputs. Kept as it was (numpy element-wise operations, numpy norms and dots,
Python's math.hypot), so a change in the C++ order of operations shows up as a mismatch."""

from __future__ import annotations

import math

import numpy as np

from cufund.geometry import (
    attitude_from_thrust_and_yaw,
    quat_conjugate,
    quat_from_matrix,
    quat_from_two_vectors,
    quat_mul,
    quat_to_matrix,
)

RATE_I_SCALE = math.radians(400.0)


class LowPassDerivative:
    def __init__(self, cutoff_hz: float) -> None:
        self.cutoff_hz = cutoff_hz
        self.value = np.zeros(3)
        self._prev = None

    def update(self, x: np.ndarray, dt: float) -> np.ndarray:
        if self._prev is None:
            self._prev = x.copy()
        alpha = dt / (dt + 1.0 / (2.0 * math.pi * self.cutoff_hz)) if self.cutoff_hz > 0 else 1.0
        self.value += alpha * ((x - self._prev) / dt - self.value)
        self._prev = x.copy()
        return self.value


class PositionReference:
    """PositionController.update's arithmetic after the mode logic (gains: PositionControlParams)."""

    def __init__(self, g, mass: float, grav: float, max_thrust: float, tau: float = 0.2) -> None:
        self.g, self.m, self.grav, self.max_thrust, self.tau = g, mass, grav, max_thrust, tau
        self.kp = np.array([g.xy_p, g.xy_p, g.z_p])
        self.kv = np.array([g.xy_vel_p, g.xy_vel_p, g.z_vel_p])
        self.ki = np.array([g.xy_vel_i, g.xy_vel_i, g.z_vel_i])
        self.kd = np.array([g.xy_vel_d, g.xy_vel_d, g.z_vel_d])
        self.acc = LowPassDerivative(g.vel_d_cutoff_hz)
        self.vel_int = np.zeros(3)
        self.offset = None
        self.t0 = 0.0

    def step(self, t, dt, p, v, sp_p, sp_v, sp_a, yaw, position_mode, handover=None):
        g, m, grav = self.g, self.m, self.grav
        acc_filt = self.acc.update(v, dt)
        v_sp = self.kp * (sp_p - p) + sp_v if position_mode else sp_v.copy()
        vxy = math.hypot(v_sp[0], v_sp[1])
        if vxy > g.xy_vel_max:
            v_sp[:2] *= g.xy_vel_max / vxy
        v_sp[2] = min(max(v_sp[2], -g.z_vel_max_dn), g.z_vel_max_up)
        v_err = v_sp - v
        acc_sp = self.kv * v_err + self.vel_int - self.kd * acc_filt + sp_a
        if handover is not None:
            self.offset, self.t0 = handover - acc_sp, t
        acc_sp = acc_sp + (0.0 if self.offset is None else self.offset * math.exp(-(t - self.t0) / self.tau))
        F, sat = self.thrust_vector(m * (acc_sp + np.array([0.0, 0.0, grav])))
        push = self.ki * v_err * dt
        keep = ~((sat > 0) & (push > 0) | (sat < 0) & (push < 0))
        self.vel_int += np.where(keep, push, 0.0)
        self.vel_int = np.minimum(np.maximum(self.vel_int, -grav), grav)
        thrust = float(np.linalg.norm(F))
        R_d = attitude_from_thrust_and_yaw(F / thrust, yaw)
        return quat_from_matrix(R_d), thrust

    def thrust_vector(self, F):
        g = self.g
        sat = np.zeros(3)
        f_min, f_max = g.thr_min * self.max_thrust, g.thr_max * self.max_thrust
        F = F.copy()
        if F[2] < f_min * math.cos(g.tilt_max):
            F[2] = f_min * math.cos(g.tilt_max)
            sat[2] = -1
        h = math.hypot(F[0], F[1])
        h_max = F[2] * math.tan(g.tilt_max)
        if h > h_max:
            F[:2] *= h_max / h
            sat[:2] = np.sign(F[:2])
        n = float(np.linalg.norm(F))
        if n > f_max:
            if F[2] >= f_max:
                F = np.array([0.0, 0.0, f_max])
            else:
                hh = math.sqrt(f_max * f_max - F[2] * F[2])
                F[:2] *= hh / max(math.hypot(F[0], F[1]), 1e-12)
                sat[:2] = np.sign(F[:2])
            sat[2] = 1
        elif n < f_min:
            F *= f_min / max(n, 1e-12)
            sat[2] = -1
        return F, sat


def attitude_reference(q, qd, yaw_rate, k, rate_max, yaw_weight, alternatives=False):
    """AttitudeController.update's arithmetic. With ``alternatives``, a list of the admissible outputs: an error
    of 180 deg (the error quaternion's w within 1e-12 of 0) has two shortest ways round, and which one the last
    bit of w picks is a rounding accident, so both are returned there."""
    R = quat_to_matrix(q)
    e_z, e_z_d = R[:, 2], quat_to_matrix(qd)[:, 2]
    qd_red = quat_from_two_vectors(e_z, e_z_d)
    if abs(qd_red[1]) > 1 - 1e-5 or abs(qd_red[2]) > 1 - 1e-5:
        qd_red = qd
    else:
        qd_red = quat_mul(qd_red, q)
    q_mix = quat_mul(quat_conjugate(qd_red), qd)
    if q_mix[0] < 0:
        q_mix = -q_mix
    w_mix = min(max(q_mix[0], -1.0), 1.0)
    z_mix = min(max(q_mix[3], -1.0), 1.0)
    yw = yaw_weight
    qd = quat_mul(qd_red, np.array([math.cos(yw * math.acos(w_mix)), 0.0, 0.0, math.sin(yw * math.asin(z_mix))]))
    qe = quat_mul(quat_conjugate(q), qd)
    if qe[0] < 0:
        qe = -qe
    out = []
    for e in [qe, -qe] if alternatives and abs(qe[0]) < 1e-12 else [qe]:
        w_sp = 2.0 * e[1:] * k
        if yaw_rate:
            w_sp += R[2, :] * yaw_rate
        out.append(np.minimum(np.maximum(w_sp, -rate_max), rate_max))
    return out if alternatives else out[0]


class RateReference:
    """RateController.control's arithmetic (allocation through cufund's C++ allocator, as before)."""

    def __init__(self, g, J, allocator) -> None:
        self.g, self.J, self.allocator = g, J, allocator
        self.kp = np.array([g.roll_p, g.pitch_p, g.yaw_p])
        self.ki = np.array([g.roll_i, g.pitch_i, g.yaw_i])
        self.kd = np.array([g.roll_d, g.pitch_d, g.yaw_d])
        self.dw = LowPassDerivative(g.d_cutoff_hz)
        self.rate_int = np.zeros(3)

    def step(self, w, w_sp, thrust, dt):
        g = self.g
        dw_filt = self.dw.update(w, dt)
        e = w_sp - w
        alpha_cmd = self.kp * e + self.rate_int - self.kd * dw_filt + g.feed_forward * w_sp
        torque = self.J @ alpha_cmd
        speeds, achieved, sat = self.allocator.allocate(thrust, torque)
        lim = g.integrator_limit
        for i in range(3):
            ei = float(e[i])
            if (sat[i + 1] > 0 and ei > 0) or (sat[i + 1] < 0 and ei < 0):
                continue
            i_factor = max(0.0, 1.0 - (ei / RATE_I_SCALE) ** 2)
            self.rate_int[i] = min(max(self.rate_int[i] + i_factor * self.ki[i] * ei * dt, -lim), lim)
        return speeds, achieved, sat


class GeometricReference:
    """GeometricController.update's force law (position and velocity modes, hand-over) before the attitude law
    and the allocation, which were already C++ (called here through their own bindings)."""

    def __init__(self, g, params, tau: float = 0.2) -> None:
        from cufund import _core

        self.g, self.params, self.tau = g, params, tau
        self.kR = np.array([g.k_R, g.k_R, g.k_R_yaw])
        self.kW = np.array([g.k_W, g.k_W, g.k_W_yaw])
        self.J = params.inertia_matrix
        self.allocator = _core.control.ControlAllocator(params.to_core())
        self.core = _core.control
        self.offset = None
        self.t0 = 0.0

    def step(self, t, p, v, q, w, sp_p, sp_v, sp_a, sp_j, yaw, yaw_rate, position_mode, handover=None):
        g, m, grav = self.g, self.params.mass, self.params.gravity
        F = m * (sp_a - g.k_v * (v - sp_v))
        F[2] += m * grav
        if position_mode:
            F -= g.k_x * m * (p - sp_p)
        if handover is not None:
            self.offset, self.t0 = handover - F, t
        F = F + (0.0 if self.offset is None else self.offset * math.exp(-(t - self.t0) / self.tau))
        thrust, M, q_d = self.core.geometric_from_force(self.J, m, self.kR, self.kW, q, w, F, sp_j, yaw, yaw_rate)
        speeds, achieved, _ = self.allocator.allocate(thrust, M)
        return q_d, thrust, speeds, achieved
