"""The pose sensor (motion capture): pose only, no velocity, with the stated noise and its latency."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import stats
from scipy.spatial.transform import Rotation

import cufund
from cufund.core.messages import Odometry, Pose, Topics
from cufund.sensors.pose_sensor import PoseSensor, PoseSensorParams
from cufund.simulator import Simulator


def _truth(t: float) -> Odometry:
    q = Rotation.from_rotvec([0.2, -0.1, 0.7]).as_quat(scalar_first=True)
    return Odometry(t, np.array([1.0, 2.0, 3.0]), np.array([0.5, 0.0, 0.0]), q, np.array([0.1, 0.2, 0.3]))


def test_a_pose_carries_position_and_attitude_only():
    assert [f.name for f in dataclasses.fields(Pose)] == ["t", "p_W", "q_WB"]
    msg = PoseSensor(PoseSensorParams(rate_hz=100.0)).measure(0.5, _truth(0.5))
    assert isinstance(msg, Pose) and not hasattr(msg, "v_W") and not hasattr(msg, "w_B")
    assert Topics.POSE.type is Pose
    np.testing.assert_array_equal(msg.p_W, [1.0, 2.0, 3.0])  # sigma 0: the true pose
    np.testing.assert_allclose(msg.q_WB, _truth(0).q_WB, atol=1e-15)


def test_noise_has_the_stated_sigmas():
    """Per-axis position error and attitude error (body-frame rotation vector, by scipy) are zero-mean with the
    stated sigmas: each sample variance inside its chi-square 99.9 % interval."""
    sp, sa, n = 5e-4, np.radians(0.1), 4000
    sensor = PoseSensor(PoseSensorParams(rate_hz=100.0, position_sigma_m=sp, attitude_sigma_rad=sa), seed=7)
    truth = _truth(0.0)
    R_true = Rotation.from_quat(truth.q_WB, scalar_first=True)
    msgs = [sensor.measure(k * 0.01, truth) for k in range(n)]
    dp = np.array([m.p_W for m in msgs]) - truth.p_W
    dth = np.array([(R_true.inv() * Rotation.from_quat(m.q_WB, scalar_first=True)).as_rotvec() for m in msgs])
    lo, hi = stats.chi2.ppf([0.0005, 0.9995], n - 1) / (n - 1)
    for err, sigma in ((dp, sp), (dth, sa)):
        var = err.var(axis=0, ddof=1) / sigma**2
        assert np.all((lo < var) & (var < hi)), var
        assert np.all(np.abs(err.mean(axis=0)) < 4 * sigma / np.sqrt(n))


def test_same_seed_same_noise_and_reset_repeats_it():
    p = PoseSensorParams(rate_hz=50.0, position_sigma_m=1e-3, attitude_sigma_rad=1e-3)
    a, b = PoseSensor(p, seed=3), PoseSensor(p, seed=3)
    first = [a.measure(0.02 * k, _truth(0)).p_W for k in range(5)]
    assert all(np.array_equal(x, b.measure(0.02 * k, _truth(0)).p_W) for k, x in enumerate(first))
    a.reset()
    assert np.array_equal(a.measure(0.0, _truth(0)).p_W, first[0])


@pytest.mark.parametrize(
    ("field", "value", "match"),
    [
        ("rate_hz", 0.0, "rate_hz must be > 0"),
        ("position_sigma_m", -1e-3, "position_sigma_m must be a finite number >= 0"),
        ("attitude_sigma_rad", float("nan"), "attitude_sigma_rad"),
        ("velocity_sigma_m_s", 0.01, "velocity_sigma_m_s"),  # no such field: motion capture measures no velocity
    ],
)
def test_bad_params_are_refused_naming_the_field(field, value, match):
    with pytest.raises((ValueError, TypeError), match=match):
        PoseSensorParams(**{field: value})


def test_a_pose_is_stamped_at_its_measurement_and_visible_latency_later():
    class Reader(cufund.Component):
        name, rate_hz, inputs = "reader", 1000.0, (Topics.POSE,)

        def setup(self, bus):
            self.sub, self.got = bus.subscribe(Topics.POSE), []

        def step(self, t, bus):
            self.got += [(t, m.t) for m in self.sub.take()]

    quad = cufund.Quadrotor(cufund.vehicle.presets.cu_astro())
    sim = Simulator(quad)
    sensor = sim.add(PoseSensor(PoseSensorParams(rate_hz=100.0)))
    sensor.latency_s = 0.008
    reader = sim.add(Reader())
    sim.run(0.1)
    seen, stamp = np.array(reader.got).T
    assert len(seen) >= 9 and np.allclose(seen - stamp, 0.008)
