"""A recorded square_vio run: ``cufund odometry`` reruns the VIO on its log, and the RMSE it reports is evo's APE
of the TUM files it writes (issue 25)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

CUFUND = Path(sys.executable).with_name("cufund")


@pytest.fixture(scope="module")
def square_vio_log(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("square_vio") / "run"
    proc = subprocess.run(
        [str(CUFUND), "run", "square_vio", "--set", "duration=6", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert (out / "run.mcap").exists(), proc.stdout + proc.stderr
    (out.parent / "stdout.txt").write_text(proc.stdout)
    return out


def test_square_vio_reports_stereo_frames_not_lidar_scans(square_vio_log):
    from cufund.core.messages import VioDiagnostics
    from cufund.logs.mcap_reader import read_mcap

    metrics = json.loads((square_vio_log / "metrics.json").read_text())
    assert metrics["vio_frames"] > 50 and metrics["vio_ms_per_frame_median"] > 0
    assert not any(k.startswith("lio_") for k in metrics), sorted(metrics)
    summary = (square_vio_log.parent / "stdout.txt").read_text()
    assert "VIO " in summary and "ms per frame" in summary and "LiDAR" not in summary, summary
    diag = [r.message for r in read_mcap(square_vio_log / "run.mcap", topics=["/estimator/diagnostics"])]
    assert len(diag) > 50 and all(isinstance(d, VioDiagnostics) for d in diag)
    assert sum(d.keyframe for d in diag) > 5 and max(d.tracked for d in diag) > 50


def test_recorded_square_vio_rmse_equals_evo_ape(square_vio_log, tmp_path):
    from evo.core import metrics, sync
    from evo.tools import file_interface

    metrics_online = json.loads((square_vio_log / "metrics.json").read_text())
    assert metrics_online["odometry_samples"] > 500  # the run flew on the VIO's IMU-rate estimate
    proc = subprocess.run(
        [str(CUFUND), "odometry", str(square_vio_log / "run.mcap"), "--out", str(tmp_path / "odo")],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    figures = json.loads((tmp_path / "odo" / "odometry.json").read_text())
    assert figures["vio_frames"] > 50 and figures["vio_frames_skipped"] == 0 and figures["vio_unpaired_images"] == 0
    assert figures["odometry_rmse_m"] < 0.05
    ref = file_interface.read_tum_trajectory_file(str(tmp_path / "odo" / "truth.tum"))
    est = file_interface.read_tum_trajectory_file(str(tmp_path / "odo" / "estimate.tum"))
    ref, est = sync.associate_trajectories(ref, est, max_diff=1e-6)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    # TUM files hold 9 decimals: the two agree to well below a micrometre
    assert ape.get_statistic(metrics.StatisticsType.rmse) == pytest.approx(figures["odometry_rmse_m"], abs=1e-7)
    assert ape.get_statistic(metrics.StatisticsType.max) == pytest.approx(figures["odometry_max_m"], abs=1e-7)


def test_odometry_on_a_bag_of_a_vio_run_names_the_run_mcap(square_vio_log, tmp_path):
    pytest.importorskip("rosbags")
    bag = tmp_path / "bag"
    proc = subprocess.run(
        [str(CUFUND), "bag", str(square_vio_log), "--out", str(bag)], capture_output=True, text=True, timeout=600
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    proc = subprocess.run(
        [str(CUFUND), "odometry", str(bag), "--out", str(tmp_path / "odo")], capture_output=True, text=True, timeout=600
    )
    assert proc.returncode != 0 and "flown on the VIO" in proc.stderr and "run.mcap" in proc.stderr, proc.stderr


@pytest.mark.parametrize("change", ["no stereo_camera", "cameras: mono"])
def test_odometry_reruns_a_vio_log_on_the_default_rig_and_on_mono(square_vio_log, tmp_path, change):
    """``cufund odometry`` on a log flown on the VIO whose scenario states no stereo_camera (``cufund run tunnel
    --set estimator.kind=vio``: the vio kind mounted its default rig, here the same as square_vio's) or flew
    ``cameras: mono``: it reruns the VIO as it flew (before: 'the VIO needs a stereo_camera sensor', and an
    IndexError traceback for mono)."""
    import yaml

    cfg = yaml.safe_load((square_vio_log / "config.yaml").read_text())
    if change == "no stereo_camera":
        del cfg["sensors"]["stereo"]
    else:
        cfg["estimator"]["cameras"] = "mono"
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(cfg))
    out = tmp_path / "odo"
    proc = subprocess.run(
        [str(CUFUND), "odometry", str(square_vio_log / "run.mcap"), "--scenario", str(scenario), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    figures = json.loads((out / "odometry.json").read_text())
    assert figures["vio_frames"] > 50 and figures["odometry_rmse_m"] < 0.1, figures
