"""IMU full-scale saturation: off by default, on under the ``realistic`` profile, and a hard landing clips.

The landing: a vehicle with its rotors stopped falls 1 m onto a landing gear (a spring-damper pushing up on the body
through the plant's external force, the rigid ground plane off), so the impact's deceleration reaches the IMU as
the body's motion: about v sqrt(k / m) ~ 40 g at touch-down speed v = sqrt(2 g h), well past the BMI088's +-24 g.
The saturated record is the unsaturated one (same seed, same noise) clipped at the range, sample for sample.
"""

import dataclasses
import math

import numpy as np
import pytest

from cufund.core.components import Component
from cufund.core.config import ConfigError
from cufund.core.messages import Topics
from cufund.scenarios import load_scenario
from cufund.scenarios.build import build_simulation
from cufund.sensors.imu import ImuParams, ImuSensor, imu_preset
from cufund.simulator import Simulator
from cufund.vehicle.presets import cu_astro
from cufund.vehicle.quadrotor import Quadrotor

G0 = 9.80665
DROP_M, GEAR_K, GEAR_C = 1.0, 6000.0, 10.0  # drop height [m], gear stiffness [N/m] and damping [N s/m]


class _Gear(Component):
    """A landing gear under the body at z = 0: pushes up with k (-z) - c v_z while compressed (never pulls)."""

    name = "gear"
    rate_hz = 1000.0

    def __init__(self, plant):
        self.plant = plant

    def step(self, t, bus):
        z, vz = float(self.plant.state.p[2]), float(self.plant.state.v[2])
        self.plant.force_ext_W[2] = max(0.0, -GEAR_K * z - GEAR_C * vz) if z < 0 else 0.0


class _ImuLog(Component):
    name = "imu_log"
    rate_hz = 1000.0
    inputs = (Topics.IMU,)

    def setup(self, bus):
        self.sub, self.got = bus.subscribe(Topics.IMU), []

    def step(self, t, bus):
        self.got += self.sub.take()


def _landing(imu_params):
    params = dataclasses.replace(cu_astro(), ground_plane=False)
    quad = Quadrotor(params)
    quad.state.p[:] = (0.0, 0.0, DROP_M)
    sim = Simulator(quad, physics_rate_hz=1000.0)
    log = _ImuLog()
    for c in (_Gear(quad), ImuSensor(imu_params, seed=7, gravity=params.gravity), log):
        sim.add(c)
    sim.run(0.8)
    return np.array([m.t for m in log.got]), np.array([m.f_I for m in log.got]), np.array([m.w_I for m in log.got])


def test_a_hard_landing_saturates_the_accelerometer_at_its_full_scale():
    bmi088 = imu_preset("bmi088")
    assert bmi088.accel_range == pytest.approx(24 * G0) and bmi088.gyro_range == pytest.approx(math.radians(2000))
    assert not bmi088.saturation  # off by default
    t, free, gyro_free = _landing(bmi088)
    t2, clipped, gyro_clipped = _landing(dataclasses.replace(bmi088, saturation=True))
    assert t.tobytes() == t2.tobytes()
    m = cu_astro().mass
    v = math.sqrt(2 * G0 * DROP_M)
    peak = free[:, 2].max()
    assert peak > 24 * G0  # the impact is beyond the range
    assert peak == pytest.approx(v * math.sqrt(GEAR_K / m), rel=0.15)  # ~ v sqrt(k/m), the undamped gear's peak
    np.testing.assert_array_equal(clipped, np.clip(free, -24 * G0, 24 * G0))  # exactly the clip, sample by sample
    assert np.count_nonzero(clipped[:, 2] == 24 * G0) >= 3
    before = t < math.sqrt(2 * DROP_M / G0) - 0.01  # in free fall, nothing clips: the records agree bit for bit
    assert before.sum() > 50 and clipped[before].tobytes() == free[before].tobytes()
    falling = before & (t > 0)  # (the first sample is taken before the first step: at rest, +g)
    assert np.abs(free[falling, 2]).max() < 1.0  # free fall reads ~0 specific force (the body's drag only)
    np.testing.assert_array_equal(gyro_free, gyro_clipped)  # no rotation, nothing to clip


def test_saturation_clips_the_gyroscope_too():
    p = dataclasses.replace(imu_preset("ideal"), gyro_range=math.radians(2000), saturation=True)
    from cufund.sensors.imu import ImuModel

    q, z = np.array([1.0, 0, 0, 0]), np.zeros(3)
    _, w = ImuModel(p).measure(q, np.array([0.0, 50.0, -50.0]), z, z)
    np.testing.assert_array_equal(w, [0.0, math.radians(2000), -math.radians(2000)])
    _, w = ImuModel(dataclasses.replace(p, saturation=False)).measure(q, np.array([0.0, 50.0, -50.0]), z, z)
    np.testing.assert_array_equal(w, [0.0, 50.0, -50.0])


def _simulated_imu_params(realism):
    built = build_simulation(load_scenario("square_lio", ["estimator=null", f"realism={realism}"]))
    (imu,) = [c for c in built.simulator.components if isinstance(c, ImuSensor)]
    return imu.model.params


def test_the_realistic_profile_turns_saturation_on_and_ideal_leaves_it_off():
    real = _simulated_imu_params("realistic")
    assert real.saturation and real.accel_range == pytest.approx(16 * G0)  # square_lio's ICM-42688-P: +-16 g
    assert not _simulated_imu_params("ideal").saturation


def test_saturation_must_be_a_boolean():
    with pytest.raises(ConfigError, match="ImuParams.saturation must be true or false"):
        ImuParams(saturation="yes")
    with pytest.raises(ConfigError, match="realism.imu.saturation must be true or false"):
        load_scenario("square_lio", ["realism.imu.saturation=3"])
