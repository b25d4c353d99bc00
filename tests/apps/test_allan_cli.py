"""`cufund allan`: the raw record, the plot and the fitted-vs-configured report."""

import json

import numpy as np
import pytest

from cufund.apps.cli import main
from cufund.sensors import imu_preset


def test_allan_command_writes_record_plot_and_report(tmp_path, capsys):
    out = tmp_path / "allan"
    assert main(["allan", "--imu", "icm42688p", "--duration", "300", "--out", str(out), "--seed", "4"]) == 0
    assert "accel_x" in capsys.readouterr().out
    rec = np.load(out / "imu.npz")
    assert rec["accel"].shape == (60_000, 3) and rec["gyro"].shape == (60_000, 3)
    np.testing.assert_allclose(rec["accel"].mean(axis=0)[2], 9.80665, atol=0.5)  # +g on z, plus turn-on bias
    assert (out / "allan.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    report = json.loads((out / "allan.json").read_text())
    params = imu_preset("icm42688p")
    nd, _, _ = params.gyro.per_axis(3)
    assert set(report["axes"]) == {f"{s}_{a}" for s in ("accel", "gyro") for a in "xyz"}
    for axis in "xyz":
        r = report["axes"][f"gyro_{axis}"]["noise_density"]
        assert r["configured"] == pytest.approx(nd[0])
        assert r["fitted"] == pytest.approx(nd[0], rel=0.1)


def test_allan_command_rejects_a_short_record(tmp_path, capsys):
    assert main(["allan", "--duration", "10", "--out", str(tmp_path)]) == 2
    assert "duration must be at least 100 s" in capsys.readouterr().err
