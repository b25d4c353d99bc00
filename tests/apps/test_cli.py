"""The ``cufund`` command line."""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from cufund.apps.cli import main
from cufund.apps.run_summary import significant
from cufund.scenarios.schema import available_scenarios


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
    assert {"config.yaml", "metrics.json", "run.mcap", "trajectory.png"} <= {p.name for p in out.iterdir()}
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


def _sig_digits(text: str) -> int:
    """Significant digits of a decimal number as written (``0.0322`` -> 3, ``30.8`` -> 3, ``1230`` -> 3)."""
    digits = text.lstrip("-").replace(".", "").lstrip("0")
    return len(digits.rstrip("0")) if "." not in text else len(digits)


def test_run_prints_a_summary_with_3_significant_digits_and_the_folder(tmp_path):
    """The console script, as a user types it: a few lines, not the metrics' JSON."""
    out = tmp_path / "sq"
    exe = Path(sys.executable).parent / "cufund"
    r = subprocess.run(
        [str(exe), "run", "square", "--out", str(out), "--no-replay", "--no-log"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    m = json.loads((out / "metrics.json").read_text())
    lines = r.stdout.splitlines()
    assert len(lines) <= 10 and "{" not in r.stdout
    assert "status: completed (done condition met)" in lines and f"run folder: {out.resolve()}" in lines
    tracking = next(line for line in lines if line.strip().startswith("tracking error"))
    rmse, worst = re.findall(r"(?:RMSE|max) ([0-9.]+) mm", tracking)
    for shown, value in ((rmse, m["tracking_rmse_m"]), (worst, m["tracking_max_m"])):
        assert _sig_digits(shown) == 3, tracking
        assert float(shown) == float(f"{1000 * value:.3g}")  # Python's own 3-significant-digit rounding
    simulated = next(line for line in lines if line.strip().startswith("simulated"))
    sim = re.search(r"simulated\s+([0-9.]+) s", simulated)
    assert sim and _sig_digits(sim.group(1)) == 3 and float(sim.group(1)) == float(f"{m['sim_time_s']:.3g}")


def test_json_prints_the_raw_metrics_only(tmp_path):
    out = tmp_path / "sq"
    exe = Path(sys.executable).parent / "cufund"
    r = subprocess.run(
        [str(exe), "run", "square", "--json", "--out", str(out), "--no-replay", "--no-log"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    printed = json.loads(r.stdout)  # stdout is the JSON and nothing else
    assert printed == json.loads((out / "metrics.json").read_text())
    assert f"run folder: {out.resolve()}" in r.stderr and "status: completed" in r.stderr


@pytest.mark.parametrize(
    ("x", "text"),
    [(0.032241, "0.0322"), (30.808, "30.8"), (5.5426, "5.54"), (1234.5, "1230"), (9.9961, "10.0"), (0.5, "0.500")],
)
def test_significant_rounds_to_3_digits_without_an_exponent(x, text):
    assert significant(x) == text
    assert float(significant(x)) == float(f"{x:.3g}")


def test_list_prints_whole_descriptions_and_the_vehicle_presets(capsys):
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    flat = " ".join(out.split())
    import cufund.scenarios

    headers = {}  # each built-in file's comment lines before its first key, read here, not by the code under test
    for path in sorted((Path(cufund.scenarios.__file__).parent / "builtin").glob("*.yaml")):
        lines = path.read_text(encoding="utf-8").splitlines()
        end = next((i for i, line in enumerate(lines) if not line.startswith("#")), len(lines))
        headers[path.stem] = " ".join(" ".join(line.lstrip("#") for line in lines[:end]).split())
    assert set(headers) == set(available_scenarios(whole=True))
    assert any(len(h) > 150 for h in headers.values())  # some run over several lines: whole, not the first one
    for name, whole in headers.items():
        assert name in out and whole in flat, name  # every word of the description, in order, none cut
    assert "vehicle presets" in out
    for preset in ("cu_astro", "iris", "crazyflie"):
        assert re.search(rf"^  {preset}\s+\S", out, re.MULTILINE), preset
    assert "thrust-to-weight 2.5" in flat  # CU-Astro: 4 k_f w_max^2 / (m g) = 19.6 N / 7.85 N
    assert max(len(line) for line in out.splitlines()) <= 120


def test_progress_bar_ends_full_when_the_run_lands_early(capsys):
    """The square lands at ~15 s of a 60 s duration: the bar ends at 100 %, not at a quarter."""
    from cufund.scenarios.build import run_scenario
    from cufund.scenarios.schema import load_scenario

    run = run_scenario(load_scenario("square"), progress=True)
    assert run.result.status.value == "completed" and run.result.sim_time_s < 30
    bars = capsys.readouterr().err.replace("\n", "\r").split("\r")
    last = [b for b in bars if b.startswith("[")][-1]
    assert last.startswith("[" + "#" * 40 + "]") and "ended early" in last
