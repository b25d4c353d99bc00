"""``odometry_ate_aligned_m``: the absolute trajectory error after the rigid alignment (Umeyama, no scale), checked
against evo's APE with SE(3) alignment and against an analytic case."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cufund.estimation.evaluation import aligned_ate, flight_window, write_tum


def test_a_rigidly_moved_copy_has_zero_aligned_error():
    rng = np.random.default_rng(4)
    p_true = rng.normal(size=(200, 3)) * [3.0, 2.0, 0.5]
    R = Rotation.from_rotvec([0.1, -0.2, 0.7]).as_matrix()
    p_est = p_true @ R.T + [1.0, -2.0, 0.3]
    assert aligned_ate(p_est, p_true) < 1e-12
    assert np.sqrt(np.mean(np.sum((p_est - p_true) ** 2, axis=1))) > 1.0  # unaligned it is far off


def test_aligned_ate_equals_evos_ape_with_se3_alignment(tmp_path):
    from evo.core import metrics, sync
    from evo.tools import file_interface

    rng = np.random.default_rng(7)
    t = np.arange(300) * 0.05
    p_true = np.column_stack([np.sin(t), np.cos(0.7 * t), 1.0 + 0.2 * t])
    q = np.tile([1.0, 0.0, 0.0, 0.0], (len(t), 1))
    drift = Rotation.from_rotvec([0.0, 0.02, 0.05]).as_matrix()
    p_est = p_true @ drift.T + [0.1, 0.0, -0.05] + rng.normal(scale=0.01, size=p_true.shape)
    write_tum(tmp_path / "est.tum", t, p_est, q)
    write_tum(tmp_path / "ref.tum", t, p_true, q)
    ref, est = sync.associate_trajectories(
        file_interface.read_tum_trajectory_file(tmp_path / "ref.tum"),
        file_interface.read_tum_trajectory_file(tmp_path / "est.tum"),
    )
    est.align(ref, correct_scale=False)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    assert aligned_ate(p_est, p_true) == pytest.approx(ape.get_statistic(metrics.StatisticsType.rmse), rel=1e-6)


def test_flight_window_is_take_off_to_touchdown():
    z = np.r_[np.zeros(10), np.linspace(0.0, 1.5, 20), np.full(30, 1.5), np.linspace(1.5, 0.0, 20), np.zeros(10)]
    w = flight_window(z)
    assert z[w.start] > 0.05 and z[w.start - 1] <= 0.05 and z[w.stop - 1] > 0.05 and z[w.stop] <= 0.05
    assert flight_window(np.zeros(5)) == slice(0, 0)


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="N >= 3"):
        aligned_ate(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ValueError, match="finite"):
        aligned_ate(np.full((4, 3), np.nan), np.zeros((4, 3)))
