"""The detector's floor frame: a plane fitted to floor returns around the pad becomes z = floor_z."""

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cufund.perception.floor_level import FloorLevel, fit_floor


def _tilted_floor(tilt_deg: float, axis: np.ndarray, n: int = 4000, seed: int = 0, noise: float = 0.02):
    """Floor returns of a level floor seen from a world frame rotated by tilt about axis (through the pad)."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-4.0, 4.0, (n, 2))  # a 3 deg tilt stays within the 0.25 m band
    floor_true = np.column_stack([xy, rng.normal(0.0, noise, n)])
    R_WT = Rotation.from_rotvec(np.radians(tilt_deg) * axis / np.linalg.norm(axis)).as_matrix()
    return floor_true @ R_WT.T, R_WT


@pytest.mark.parametrize("tilt", [0.0, 0.3, 1.0, 3.0])
def test_the_fitted_floor_is_level_in_the_detector_frame(tilt):
    pts_W, R_WT = _tilted_floor(tilt, np.array([1.0, 2.0, 0.0]))
    level = fit_floor(pts_W, np.zeros(3), 0.0)
    assert level is not None
    assert level.tilt_deg == pytest.approx(tilt, abs=0.04)  # the slope of 4000 2-cm returns: ~0.01 deg
    p_D, _ = level.pose_to_D(pts_W, np.eye(3))
    assert abs(np.mean(p_D[:, 2])) < 2e-3 and np.std(p_D[:, 2]) < 0.025
    # the floor frame is the true (level) one up to a yaw: its z axis is the true up
    z_W = level.vector_to_W(np.array([0.0, 0.0, 1.0]))
    assert math.degrees(math.acos(np.clip(z_W @ R_WT[:, 2], -1, 1))) < 0.04


def test_to_D_and_back_is_the_identity_and_rigid():
    pts_W, _ = _tilted_floor(2.0, np.array([0.0, 1.0, 0.0]))
    level = fit_floor(pts_W, np.array([0.5, -0.3, 0.0]), 0.0)
    x = np.random.default_rng(1).normal(size=(50, 3)) * 4
    x_D, R_D = level.pose_to_D(x, np.tile(np.eye(3), (50, 1, 1)))
    np.testing.assert_allclose(level.point_to_W(x_D), x, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(x_D[1:] - x_D[:-1], axis=1), np.linalg.norm(x[1:] - x[:-1], axis=1))
    np.testing.assert_allclose(R_D[0] @ np.eye(3), level.R_DW)


def test_walls_and_frame_feet_do_not_tilt_the_fit():
    pts_W, _ = _tilted_floor(0.5, np.array([1.0, 0.0, 0.0]))
    rng = np.random.default_rng(2)
    wall = np.column_stack([np.full(800, 4.0), rng.uniform(-5, 5, 800), rng.uniform(0.0, 0.25, 800)])
    level = fit_floor(np.vstack([pts_W, wall]), np.zeros(3), 0.0)
    assert level.tilt_deg == pytest.approx(0.5, abs=0.05)


def test_no_floor_in_view_keeps_the_world_horizontal():
    assert fit_floor(np.zeros((10, 3)), np.zeros(3), 0.0) is None
    steep, _ = _tilted_floor(20.0, np.array([1.0, 0.0, 0.0]), noise=0.0)
    assert fit_floor(steep, np.zeros(3), 0.0, band=5.0) is None
    assert FloorLevel().tilt_deg == 0.0
