"""The LIO's start with no truth prior: the pad gives origin and yaw; roll, pitch and biases come from the IMU."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cufund.core.config import ConfigError
from cufund.estimation import LioCore, LioParams
from cufund.sensors import ImuModel, imu_preset
from cufund.sensors.calibration import after_calibration


def _start(q_WB, imu, pad_yaw, seconds=1.2):
    core = LioCore(LioParams(p_WB0=(1.0, 2.0, 0.0), pad_yaw=pad_yaw))
    k = int(seconds * 200)
    f, w = imu.measure_static(k, q_WB)
    for i in range(k):
        core.add_imu(i / 200.0, f[i], w[i])
    assert core.initialised
    s = core.estimate
    return Rotation.from_matrix(s.R_WI), s


@pytest.mark.parametrize("tilt_deg, yaw", [(0.0, 0.0), (3.0, 0.4), (2.0, -2.5)])
def test_a_tilted_pad_is_found_from_gravity_and_the_yaw_is_the_pads(tilt_deg, yaw):
    axis = np.array([0.6, -0.8, 0.0])
    R_true = Rotation.from_euler("z", yaw) * Rotation.from_rotvec(math.radians(tilt_deg) * axis)
    q = R_true.as_quat()[[3, 0, 1, 2]]
    imu = ImuModel(after_calibration(imu_preset("icm42688p")), seed=5)  # a perfectly calibrated accelerometer
    R_est, s = _start(q, imu, yaw_of_rotation(R_true))
    assert (R_est.inv() * R_true).magnitude() < math.radians(0.03)  # white noise over a second: hundredths
    np.testing.assert_allclose(s.bias_gyr, imu.bias[1], atol=2e-4)  # the static mean rate
    np.testing.assert_allclose(s.p_W, [1.0, 2.0, 0.0], atol=1e-3)  # the pad (propagated a few samples on)


def yaw_of_rotation(R):
    return float(R.as_euler("ZYX")[0])


def test_a_residual_accelerometer_bias_reads_as_a_tilt_of_bias_over_g():
    imu = ImuModel(after_calibration(imu_preset("icm42688p"), 0.05), seed=11)  # 5 mg
    b = imu.bias[0]
    R_est, _ = _start(np.array([1.0, 0.0, 0.0, 0.0]), imu, 0.0)
    # at rest f = R^T g e_z + b: the estimate levels f, so its up axis leans by the horizontal bias over g
    roll, pitch = R_est.as_euler("ZYX")[2], R_est.as_euler("ZYX")[1]
    assert roll == pytest.approx(math.atan2(b[1], 9.80665 + b[2]), abs=3e-4)
    assert pitch == pytest.approx(-math.asin(b[0] / np.linalg.norm(b + [0, 0, 9.80665])), abs=3e-4)


@pytest.mark.parametrize("key", ["q_WB0", "pad_attitude_known"])
def test_the_removed_truth_priors_are_refused_by_name(key):
    with pytest.raises(ConfigError, match=f"{key} was removed"):
        LioParams.from_dict({key: True})


def test_an_imu_mounted_at_45_deg_of_yaw_starts_as_well():
    """The roll/pitch prior lives in the IMU frame's tangent space: turned by the mounting, not just permuted."""
    import dataclasses

    q_BI = (math.cos(math.pi / 8), 0.0, 0.0, math.sin(math.pi / 8))
    part = dataclasses.replace(after_calibration(imu_preset("icm42688p")), q_BI=q_BI)
    imu = ImuModel(part, seed=3)
    core = LioCore(LioParams(imu=part, p_WB0=(0.0, 0.0, 0.0), pad_yaw=0.3))
    R_true = Rotation.from_euler("z", 0.3) * Rotation.from_rotvec(np.radians([2.0, -1.0, 0.0]))
    f, w = imu.measure_static(240, R_true.as_quat()[[3, 0, 1, 2]])
    for i in range(240):
        core.add_imu(i / 200.0, f[i], w[i])
    R_WB = Rotation.from_matrix(core.estimate.R_WI) * Rotation.from_quat(np.r_[q_BI[1:], q_BI[0]]).inv()
    assert (R_WB.inv() * R_true).magnitude() < math.radians(0.03)
