"""The motor failure detector's momentum observer against a rigid body integrated by scipy, and the attitude
failure detector against scipy's Euler angles."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from cufund.missions.failsafe_motor import AttitudeFailureDetector, MotorFailureDetector
from cufund.vehicle import presets


def _fly(eff: np.ndarray, w0: np.ndarray, t_end: float = 1.0, rate_hz: float = 1000.0):
    """Hover speeds commanded on every rotor; the true rotors deliver ``eff`` of their thrust and drag torque. The
    body's rotation J w' = tau - w x J w integrated by scipy; the detector fed the exact rates at ``rate_hz``."""
    p = presets.cu_astro()
    J = p.inertia_matrix
    A = p.allocation_matrix()
    w_h = p.hover_rotor_speed
    thrust = p.k_f * w_h**2 * np.ones(4)
    tau_true = A[1:] @ (thrust * eff)
    tau_cmd = A[1:] @ thrust

    def f(t, w):
        return np.linalg.solve(J, tau_true - np.cross(w, J @ w))

    ts = np.arange(0.0, t_end, 1.0 / rate_hz)
    sol = solve_ivp(f, (0.0, t_end), w0, t_eval=ts, rtol=1e-10, atol=1e-12)
    det = MotorFailureDetector(p, threshold=0.5, t_trigger=0.15, bandwidth=15.0)
    det.command(0.0, np.full(4, w_h))
    out = []
    for k, t in enumerate(ts):
        if det.due(t):
            det.gyro(t, sol.y[:, k])
            out.append((t, np.array(det.residual)))
    return det, tau_true - tau_cmd, out


def test_residual_follows_the_lost_torque_as_a_first_order_lag():
    eff = np.array([1.0, 0.4, 1.0, 1.0])
    det, tau_ext, out = _fly(eff, np.zeros(3))
    t0 = out[0][0]
    for t, r in out[1:]:
        expected = tau_ext * (1.0 - math.exp(-det.K * (t - t0)))  # r' = K (tau_ext - r), r(t0) = 0
        assert np.linalg.norm(r - expected) < 0.05 * np.linalg.norm(tau_ext), (t, r, expected)
    # fires once the lag crosses the threshold and stays above it for t_trigger, and names rotor 1
    level = np.linalg.norm(tau_ext[:2]) / det.torque_scale
    t_cross = t0 - math.log(1.0 - det.threshold / level) / det.K
    assert det.failed and det.motor == 1
    assert det.t_failed == pytest.approx(t_cross + det.t_trigger, abs=0.012)


@pytest.mark.parametrize("motor", [0, 1, 2, 3])
def test_each_stopped_rotor_is_named(motor):
    eff = np.ones(4)
    eff[motor] = 0.0
    det, _, _ = _fly(eff, np.zeros(3), t_end=0.6)
    assert det.failed and det.motor == motor


def test_a_healthy_spinning_body_leaves_no_residual():
    # every rotor as commanded, the body tumbling: only the gyroscopic term acts, which the observer models
    det, tau_ext, out = _fly(np.ones(4), np.array([2.0, -1.5, 3.0]))
    assert np.allclose(tau_ext, 0.0)
    assert max(np.linalg.norm(r) for _, r in out) < 0.01 * det.torque_scale
    assert not det.failed and det.peak < 0.01


def test_a_small_loss_stays_below_the_threshold():
    det, _, _ = _fly(np.array([1.0, 1.0, 0.8, 1.0]), np.zeros(3))
    assert not det.failed
    assert det.peak == pytest.approx(0.2, rel=0.05)  # (1 - 0.8) of one rotor's hover torque


def test_attitude_detector_roll_pitch_match_scipy_and_wait_for_ttri():
    for roll, pitch, yaw in [(0.3, -0.2, 1.0), (-1.2, 0.5, -2.0), (0.0, 1.3, 0.4)]:
        q_xyzw = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_quat()
        q = np.array([q_xyzw[3], *q_xyzw[:3]])
        det = AttitudeFailureDetector(60.0, 60.0, 0.3, 0.3)
        beyond = abs(roll) > math.radians(60) or abs(pitch) > math.radians(60)
        assert det.update(0.0, q) is False  # never at once
        assert det.update(0.29, q) is False
        assert det.update(0.31, q) is beyond
        if beyond:
            assert ("roll" if abs(roll) > math.radians(60) else "pitch") in det.reason


def test_attitude_detector_upside_down_and_off():
    q = np.array([0.0, 1.0, 0.0, 0.0])  # 180 deg roll
    det = AttitudeFailureDetector(60.0, 60.0, 0.3, 0.3)
    det.update(0.0, q)
    assert det.update(0.3, q)
    off = AttitudeFailureDetector(0.0, 0.0, 0.3, 0.3)
    off.update(0.0, q)
    assert not off.update(1.0, q)
