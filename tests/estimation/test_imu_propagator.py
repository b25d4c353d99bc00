"""The IMU propagator (error-state Kalman filter on pose corrections) against an analytic motion: velocity and
both IMU biases come from the poses alone, late poses are applied at their stamps, nothing before the first."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import cufund
from cufund.core.messages import Imu, Pose, Topics
from cufund.estimation.imu_propagator import ImuPropagator, ImuPropagatorParams
from cufund.simulator import Simulator

G = 9.81
W_B = np.array([0.15, -0.1, 0.4])  # constant body rate [rad/s]: the attitude is q0 * Exp(W_B t), exactly
Q0 = Rotation.from_rotvec([0.05, -0.03, 0.3])
B_A = np.array([0.12, -0.08, 0.15])  # the IMU's accelerometer bias [m/s^2] (12-15 mg)
B_G = np.array([0.004, -0.006, 0.003])  # gyro bias [rad/s] (0.2-0.35 deg/s)


def motion(t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, Rotation]:
    """Position, velocity, acceleration (world) and attitude at ``t``: a Lissajous figure climbing."""
    p = np.array([np.sin(t), 1 - np.cos(0.7 * t), 0.1 * t * t])
    v = np.array([np.cos(t), 0.7 * np.sin(0.7 * t), 0.2 * t])
    a = np.array([-np.sin(t), 0.49 * np.cos(0.7 * t), 0.2])
    return p, v, a, Q0 * Rotation.from_rotvec(W_B * t)


class AnalyticImu(cufund.Component):
    name, rate_hz, outputs = "analytic_imu", 200.0, (Topics.IMU,)

    def step(self, t, bus):
        _, _, a, R = motion(t)
        f_B = R.inv().apply(a + [0.0, 0.0, G]) + B_A
        bus.publish(Topics.IMU, Imu(t, f_B, W_B + B_G))


class AnalyticPose(cufund.Component):
    """Exact poses at ``rate_hz``, stamped at their time, visible ``latency_s`` later; ``stamp_late`` stamps them
    at their arrival instead (what a filter that ignores the delay effectively does)."""

    name, outputs = "analytic_pose", (Topics.POSE,)

    def __init__(self, rate_hz=50.0, latency_s=0.0, stamp_late=False, t0=0.0):
        self.rate_hz, self.latency_s, self.stamp_late, self.t0 = rate_hz, latency_s, stamp_late, t0

    def step(self, t, bus):
        if t < self.t0:
            return
        p, _, _, R = motion(t)
        bus.publish(
            Topics.POSE, Pose(t + (self.latency_s if self.stamp_late else 0.0), p, R.as_quat(scalar_first=True))
        )


def rms_after(out, err, t0=10.0):
    return float(np.sqrt(np.mean(err[out["t"] > t0] ** 2)))


def run(duration=20.0, **pose):
    sim = Simulator(None, record_topics=(Topics.ESTIMATE,))
    sim.add(AnalyticImu())
    sim.add(AnalyticPose(**pose))
    est = sim.add(ImuPropagator(200.0, G))
    out = sim.run(duration).topics[Topics.ESTIMATE]
    truth = [motion(t) for t in out["t"]]
    p_err = np.linalg.norm(out["p_W"] - np.array([m[0] for m in truth]), axis=1)
    v_err = np.linalg.norm(out["v_W"] - np.array([m[1] for m in truth]), axis=1)
    return est, out, p_err, v_err


@pytest.fixture(scope="module")
def delayed():
    return run(latency_s=0.03)


def test_velocity_and_biases_come_from_the_poses(delayed):
    """The poses carry no velocity; the filter starts at zero velocity and zero biases and converges to the
    analytic velocity and to the IMU's true biases."""
    est, out, p_err, v_err = delayed
    late = out["t"] > 10.0
    assert np.max(v_err[late]) < 0.005  # [m/s]
    assert np.max(p_err[late]) < 5e-4  # [m] (the pose sigma the filter is told; exact poses, Euler integration)
    np.testing.assert_allclose(est.b_a, B_A, atol=0.01)
    np.testing.assert_allclose(est.b_g, B_G, atol=5e-4)
    assert v_err[0] > 0.5  # it did start without the true velocity (|v(0)| = 1 m/s)


def test_a_late_pose_acts_at_its_stamp(delayed):
    """30 ms late poses applied at their stamps track as well as poses without delay; the same poses taken as
    if measured on arrival leave a lag error of about |v| x 30 ms."""
    _, out, p_err, _ = delayed
    _, out_now, p_now, _ = run(latency_s=0.0)
    _, out_naive, p_naive, _ = run(latency_s=0.03, stamp_late=True)
    delayed_rms, now_rms, naive_rms = rms_after(out, p_err), rms_after(out_now, p_now), rms_after(out_naive, p_naive)
    assert delayed_rms < 1.5 * now_rms
    assert naive_rms > 10 * delayed_rms and naive_rms > 0.01  # ~ 30 ms at about 1 m/s


def test_nothing_before_the_first_pose_then_its_attitude():
    sim = Simulator(None, record_topics=(Topics.ESTIMATE,))
    sim.add(AnalyticImu())
    sim.add(AnalyticPose(rate_hz=50.0, t0=0.5))
    sim.add(ImuPropagator(200.0, G))
    out = sim.run(0.6).topics[Topics.ESTIMATE]
    assert out["t"][0] == pytest.approx(0.5)
    R0 = motion(0.5)[3]
    angle = (R0.inv() * Rotation.from_quat(out["q_WB"][0], scalar_first=True)).magnitude()
    assert angle < 1e-9


def test_params_are_checked_naming_the_field():
    with pytest.raises(ValueError, match="estimator.position_sigma_m must be > 0"):
        ImuPropagatorParams(position_sigma_m=0.0)
    with pytest.raises(ValueError, match="estimator.gyro_noise_density must be a finite number"):
        ImuPropagatorParams(gyro_noise_density=float("inf"))


def test_a_pose_older_than_the_kept_history_is_counted_and_applied_to_the_oldest_state():
    sim = Simulator(None, record_topics=(Topics.ESTIMATE,))
    sim.add(AnalyticImu())
    sim.add(AnalyticPose(rate_hz=50.0, latency_s=0.05))
    est = sim.add(ImuPropagator(200.0, G, params=ImuPropagatorParams(buffer_s=0.02)))
    out = sim.run(5.0).topics[Topics.ESTIMATE]
    assert est.late_corrections > 200 and est.corrections == est.late_corrections + 1  # all but the first
    assert np.all(np.isfinite(out["p_W"])) and np.all(np.isfinite(out["v_W"]))
