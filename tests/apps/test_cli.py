"""The ``cufund`` command line."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from cufund.apps.cli import main


def test_help_lists_scenarios(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--help"])
    assert e.value.code == 0
    out = capsys.readouterr().out
    assert "square" in out and "§3.1" in out and "run" in out


def test_console_script_installed():
    exe = Path(sys.executable).parent / "cufund"
    r = subprocess.run([str(exe), "--help"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "square" in r.stdout


def test_run_square_writes_folder(tmp_path, capsys):
    out = tmp_path / "sq"
    assert main(["run", "square", "--controller", "geometric", "--out", str(out), "--no-replay"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["config.yaml", "metrics.json", "run.mcap", "trajectory.png"]
    m = json.loads((out / "metrics.json").read_text())
    assert m["status"] == "completed" and m["tracking_rmse_m"] <= 0.02
    printed = capsys.readouterr().out
    assert f"run folder: {out.resolve()}" in printed and "status: completed" in printed
    # config.yaml runs again through the same command
    assert main(["run", str(out / "config.yaml"), "--out", str(tmp_path / "again"), "--no-replay"]) == 0
    m2 = json.loads((tmp_path / "again" / "metrics.json").read_text())
    assert m2["tracking_rmse_m"] == m["tracking_rmse_m"]


def test_bad_scenario_exits_2(capsys):
    assert main(["run", "nosuch"]) == 2
    assert "unknown scenario 'nosuch'" in capsys.readouterr().err


def test_odometry_on_a_recorded_log(tmp_path, capsys):
    """cufund odometry re-runs the LIO open loop on a run.mcap, with the extrinsics of the scenario recorded in it."""
    run = tmp_path / "run"
    assert main(["run", "square_lio", "--set", "duration=6", "--out", str(run), "--no-replay"]) == 1  # timeout
    closed_loop = json.loads((run / "metrics.json").read_text())
    assert closed_loop["lio_scans"] > 40 and closed_loop["lio_ms_per_scan_median"] > 0
    odo = tmp_path / "odo"
    assert main(["odometry", str(run / "run.mcap"), "--out", str(odo)]) == 0
    figures = json.loads((odo / "odometry.json").read_text())
    assert figures["odometry_rmse_m"] <= 0.01 and figures["odometry_max_m"] <= 0.03
    # the same estimator on the same data: the open-loop figures agree with the closed-loop ones
    assert abs(figures["odometry_rmse_m"] - closed_loop["odometry_rmse_m"]) < 0.002
    assert (odo / "estimate.tum").read_text().count("\n") == figures["odometry_samples"]
    assert (odo / "odometry.png").read_bytes()[:4] == b"\x89PNG"
    capsys.readouterr()
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"not an mcap file")
    assert main(["odometry", str(bad), "--out", str(tmp_path / "o2")]) == 2
    assert "not a complete MCAP log" in capsys.readouterr().err
