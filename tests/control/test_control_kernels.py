"""The controllers' C++ kernels (cufund._core.control PositionControl, AttitudeControl, RateControl,
GeometricControl) against their Python/numpy reference (tests/support/control_reference.py) on random inputs: same outputs
and same controller state, bit for bit (with a diagonal inertia, as every preset has; within 1e-12 relative for a
full one). Bit for bit holds where numpy's short dot products (OpenBLAS's ddot) accumulate as one fused
multiply-add per element in order, which the kernels reproduce (cpp/control/reference_arithmetic.h); on a CPU whose
BLAS kernel sums otherwise, the reference itself changes in the last bits, and the outputs are compared to 1e-9."""

from __future__ import annotations

import dataclasses
import math
from fractions import Fraction

import numpy as np
import pytest

import cufund
from control_reference import RATE_I_SCALE, GeometricReference, PositionReference, RateReference, attitude_reference
from cufund import _core
from cufund.control import AttitudeControlParams, PositionControlParams
from cufund.control.rate_control import _RATE_I_SCALE
from cufund.scenarios import load_scenario

PARAMS = cufund.vehicle.presets.cu_astro()


def _numpy_dots_are_fma_in_order() -> bool:
    """Whether np.dot of 3- and 4-vectors rounds as a[0] b[0], then fma(a[i], b[i], sum) in order (exact rational
    arithmetic, rounded once per step)."""
    rng = np.random.default_rng(0)
    for n in (3, 4):
        for _ in range(300):
            a, b = rng.normal(size=n), rng.normal(size=n)
            s = float(a[0] * b[0])
            for i in range(1, n):
                s = float(Fraction(float(a[i])) * Fraction(float(b[i])) + Fraction(s))
            if float(np.dot(a, b)) != s:
                return False
    return True


EXACT = _numpy_dots_are_fma_in_order()


def same(x, y) -> bool:
    """Bit for bit where the reference's dot products are reproducible (EXACT), else to 1e-9 relative."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    return np.array_equal(x, y) if EXACT else bool(np.allclose(x, y, rtol=1e-9, atol=1e-12))


SQUARE = load_scenario("square").controller.params


def unit_quaternion(rng):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def vec(rng, scale):
    return rng.normal(size=3) * scale


POSITION_GAINS = [
    SQUARE.position,
    PositionControlParams(),
    PositionControlParams(xy_vel_max=0.5, z_vel_d=0.4, vel_d_cutoff_hz=0.0, thr_max=0.6, thr_min=0.3, tilt_max=0.3),
]


@pytest.mark.parametrize("gains", POSITION_GAINS)
def test_position_kernel_matches_reference(gains):
    rng = np.random.default_rng(7)
    mass, grav = PARAMS.mass, PARAMS.gravity
    max_thrust = 4.0 * PARAMS.k_f * PARAMS.rotor_speed_max**2
    ref = PositionReference(gains, mass, grav, max_thrust)
    core = _core.control.PositionControl(mass, grav, max_thrust, gains.vel_d_cutoff_hz, 0.2)
    core.set_gains(
        ref.kp,
        ref.kv,
        ref.ki,
        ref.kd,
        gains.xy_vel_max,
        gains.z_vel_max_up,
        gains.z_vel_max_dn,
        gains.tilt_max,
        gains.thr_min,
        gains.thr_max,
    )
    t, dt = 0.0, 1.0 / 250.0
    saturated = {"tilt": 0, "max": 0, "min": 0}
    for k in range(3000):
        t += dt
        scale = 10.0 ** rng.uniform(-3, 1.5)
        p, v = vec(rng, 3.0), vec(rng, scale)
        sp_p, sp_v, sp_a = p + vec(rng, scale), vec(rng, scale), vec(rng, scale)
        yaw = rng.uniform(-math.pi, math.pi)
        position_mode = bool(rng.uniform() < 0.8)
        handover = vec(rng, 5.0) if k == 0 or rng.uniform() < 0.02 else None
        q_ref, f_ref = ref.step(t, dt, p, v, sp_p, sp_v.copy(), sp_a, yaw, position_mode, handover)
        q, f = core.step(t, dt, p, v, sp_p, sp_v, sp_a, yaw, position_mode, handover)
        assert same(q, q_ref) and same(f, f_ref), (k, q, q_ref, f, f_ref)
        assert same(core.vel_int, ref.vel_int), k
        assert same(core.acc_filt, ref.acc.value), k
        assert not q.flags.writeable and q.base is None  # a message takes it as it is
        saturated["max"] += f >= gains.thr_max * max_thrust * (1 - 1e-12)
        saturated["min"] += f <= gains.thr_min * max_thrust * (1 + 1e-12)
        z = quat_z(q)
        saturated["tilt"] += z[2] <= math.cos(gains.tilt_max) * (1 + 1e-9)
    assert min(saturated.values()) > 50, saturated  # every limit was exercised


def quat_z(q):
    w, x, y, z = q
    return np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])


@pytest.mark.parametrize("gains", [SQUARE.attitude, AttitudeControlParams(), AttitudeControlParams(yaw_p=20.0)])
def test_attitude_kernel_matches_reference(gains):
    rng = np.random.default_rng(8)
    rp = 0.5 * (gains.roll_p + gains.pitch_p)
    k = np.array([gains.roll_p, gains.pitch_p, rp])
    rate_max = np.array([gains.roll_rate_max, gains.pitch_rate_max, gains.yaw_rate_max])
    yaw_weight = min(max(gains.yaw_p / rp, 0.0), 1.0)
    core = _core.control.AttitudeControl()
    core.set_gains(k, rate_max, yaw_weight)
    flipped = 0
    for i in range(5000):
        q = unit_quaternion(rng)
        if i % 10 == 0:  # thrust axes (nearly) opposite: the full-attitude branch
            qd = np.array([-q[1], q[0], q[3], -q[2]])  # q * [0, 1, 0, 0]: rolled by 180 deg
            flipped += 1
        else:
            qd = unit_quaternion(rng) if i % 2 else q + rng.normal(size=4) * 0.05
            qd = qd / np.linalg.norm(qd)
        yaw_rate = 0.0 if i % 3 == 0 else rng.normal() * 2.0
        w_refs = attitude_reference(q, qd, yaw_rate, k, rate_max, yaw_weight, alternatives=True)
        w = core.rate_setpoint(q, qd, yaw_rate)
        assert any(same(w, w_ref) for w_ref in w_refs), (i, w, w_refs)
    assert flipped == 500


@pytest.mark.parametrize("J", ["diagonal", "full"])
def test_rate_kernel_matches_reference(J):
    rng = np.random.default_rng(9)
    params = PARAMS
    if J == "full":
        A = rng.normal(size=(3, 3)) * 1e-4
        params = dataclasses.replace(PARAMS, inertia=tuple(map(tuple, PARAMS.inertia_matrix + A @ A.T)))
    gains = dataclasses.replace(SQUARE.rate, feed_forward=0.3)
    allocator = _core.control.ControlAllocator(params.to_core())
    ref = RateReference(gains, params.inertia_matrix, allocator)
    core = _core.control.RateControl(params.to_core(), gains.d_cutoff_hz, _RATE_I_SCALE)
    core.set_gains(ref.kp, ref.ki, ref.kd, gains.feed_forward, gains.integrator_limit)
    max_thrust = allocator.max_thrust
    exact = J == "diagonal"
    saturated = 0
    for i in range(4000):
        scale = 10.0 ** rng.uniform(-2, 1)
        w, w_sp = vec(rng, scale), vec(rng, scale)
        thrust = rng.uniform(0.0, 1.1 * max_thrust)
        speeds_ref, achieved_ref, sat_ref = ref.step(w, w_sp, thrust, 1.0 / 500.0)
        speeds, f, torque, sat = core.step(w, w_sp, thrust, 1.0 / 500.0)
        achieved = np.array([f, *torque])
        saturated += any(sat[1:])
        assert sat == sat_ref, i
        if exact:
            assert same(speeds, speeds_ref) and same(achieved, achieved_ref), i
            assert same(core.rate_int, ref.rate_int), i
        else:
            # compared as rotor thrusts (speed^2): a rotor at the bottom of its range is sqrt of a rounding error
            np.testing.assert_allclose(speeds**2, speeds_ref**2, rtol=1e-12, atol=1e-12 * PARAMS.rotor_speed_max**2)
            np.testing.assert_allclose(achieved, achieved_ref, rtol=1e-12, atol=1e-15)
            np.testing.assert_allclose(core.rate_int, ref.rate_int, rtol=1e-12, atol=1e-15)
        assert not speeds.flags.writeable and not torque.flags.writeable
    assert saturated > 200  # the anti-windup branch was exercised


def test_rate_i_scale_is_pythons():
    assert _RATE_I_SCALE == RATE_I_SCALE


def test_kernels_reject_bad_input():
    core = _core.control.PositionControl(1.0, 9.81, 30.0, 5.0, 0.2)
    z = np.zeros(3)
    with pytest.raises(ValueError, match="p_W"):
        core.step(0.0, 0.004, np.array([0.0, np.nan, 0.0]), z, z, z, z, 0.0, True)
    with pytest.raises(ValueError, match="v_W"):
        core.step(0.0, 0.004, z, np.zeros(4), z, z, z, 0.0, True)
    with pytest.raises(ValueError, match="dt"):
        core.step(0.0, 0.0, z, z, z, z, z, 0.0, True)
    with pytest.raises(ValueError, match="mass"):
        _core.control.PositionControl(-1.0, 9.81, 30.0, 5.0, 0.2)
    rate = _core.control.RateControl(PARAMS.to_core(), 30.0, 1.0)
    with pytest.raises(ValueError, match="w_sp"):
        rate.step(z, [0.0, math.inf, 0.0], 5.0, 0.002)
    with pytest.raises(TypeError, match="thrust"):
        rate.step(z, z, "5", 0.002)
    att = _core.control.AttitudeControl()
    with pytest.raises(ValueError, match="yaw_weight"):
        att.set_gains(z, z, 2.0)
    with pytest.raises(ValueError, match="q_WB_d"):
        att.rate_setpoint(np.array([1.0, 0, 0, 0]), z, 0.0)


def test_geometric_kernel_matches_reference():
    gains = SQUARE.geometric
    ref = GeometricReference(gains, PARAMS)
    core = _core.control.GeometricControl(PARAMS.to_core(), 0.2)
    core.set_gains(gains.k_x, gains.k_v, ref.kR, ref.kW)
    rng = np.random.default_rng(10)
    t = 0.0
    for k in range(3000):
        t += 0.002
        scale = 10.0 ** rng.uniform(-3, 1)
        p, v, w = vec(rng, 3.0), vec(rng, scale), vec(rng, scale)
        q = unit_quaternion(rng)
        sp = [p + vec(rng, scale), vec(rng, scale), vec(rng, scale), vec(rng, scale)]
        yaw, yaw_rate = rng.uniform(-math.pi, math.pi), rng.normal()
        position_mode = bool(rng.uniform() < 0.8)
        handover = vec(rng, 10.0) if k == 0 or rng.uniform() < 0.02 else None
        q_ref, f_ref, speeds_ref, achieved_ref = ref.step(t, p, v, q, w, *sp, yaw, yaw_rate, position_mode, handover)
        q_d, f, speeds, f_a, torque = core.step_force(t, p, v, q, w, *sp, yaw, yaw_rate, position_mode, handover)
        assert same(q_d, q_ref) and same(f, f_ref), k
        assert same(speeds, speeds_ref) and same(np.array([f_a, *torque]), achieved_ref), k
