"""Plausibility checks at load (issue 24, item 5): values that are well-formed but surely a mistake make ``cufund``
exit 2 with the field named, before anything runs: degrees in a radian field, speed and acceleration limits the
vehicle cannot reach, a YAML key given twice. The bounds are checked against the vehicle model worked by hand."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cufund.apps.cli import main as cli_main
from cufund.core.config import ConfigError, load_yaml_text
from cufund.scenarios.plausibility import SPEED_CEILING, checked_fields, field_units, reach
from cufund.scenarios.schema import TrajectoryConfig, available_scenarios, load_scenario
from cufund.vehicle import presets

CUFUND = Path(sys.executable).with_name("cufund")


def _cufund(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([str(CUFUND), *args], capture_output=True, text=True, timeout=300, check=False, cwd=cwd)


def _cli(*args: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """``cufund *args`` in this process (the console script returns main's code): (exit code, stderr). The process
    itself is run once, by test_a_sweep_spec_with_a_duplicate_key_exits_2 (a second of start-up per case)."""
    code = cli_main(list(args))
    return code, capsys.readouterr().err


SQUARE_WITH = """\
name: plausibility
vehicle: cu_astro
controller: pid
trajectory:
  waypoints: [[0, 0, 1.5], [1, 0, 1.5], [1, 1, 1.5]]
{extra}
"""

# (the trajectory lines of a scenario file, the field the error must name, words it must say)
CASES = [
    ("  yaw: [0, 90, 0]", "trajectory.yaw[1]", "did you mean degrees?"),
    ("  yaw: [0, 0, -7]", "trajectory.yaw[2]", "did you mean degrees?"),
    ("  v_max: 1500", "trajectory.v_max", "m/s"),
    ("  a_max: 100", "trajectory.a_max", "m/s^2"),
    ("  move_v_max: 200", "trajectory.move_v_max", "m/s"),
    ("  hover_s: 1\n  v_max: 1\n  hover_s: 2", "trajectory.hover_s", "duplicate key 'hover_s' at line 8"),
]


@pytest.mark.parametrize(("extra", "field", "words"), CASES, ids=[c[1] for c in CASES])
def test_a_surely_mistaken_scenario_file_exits_2_naming_the_field(tmp_path, monkeypatch, capsys, extra, field, words):
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "s.yaml"
    path.write_text(SQUARE_WITH.format(extra=extra), encoding="utf-8")
    code, err = _cli("run", str(path), "--out", str(tmp_path / "run"), capsys=capsys)
    assert code == 2, err
    assert field in err and words in err, err
    assert "Traceback" not in err
    assert not (tmp_path / "run").exists()  # refused before anything ran


@pytest.mark.parametrize(
    ("override", "field"),
    [
        ("controller.position.xy_vel_max=500", "controller.position.xy_vel_max"),  # a kind's params, nested
        ("controller.geometric.i_max=1000", "controller.geometric.i_max"),
    ],
)
def test_set_overrides_are_checked_as_files_are(tmp_path, monkeypatch, capsys, override, field):
    monkeypatch.chdir(tmp_path)
    code, err = _cli("run", "square", "--set", override, "--out", str(tmp_path / "run"), capsys=capsys)
    assert code == 2 and field in err, err


def test_a_kinds_documented_radian_field_is_found_without_being_listed():
    """``estimator.pad_yaw`` is documented [rad] in the LIO's params; nothing names it in the checks."""
    assert field_units(type(load_scenario("tunnel").estimator.params))["pad_yaw"] == "rad"
    with pytest.raises(ConfigError, match=r"estimator\.pad_yaw = 90 .*did you mean degrees"):
        load_scenario("tunnel", ["estimator.pad_yaw=90"])
    assert load_scenario("tunnel", ["estimator.pad_yaw=3.1"]).estimator.params.pad_yaw == 3.1
    # the position loop's largest tilt [rad]: its own bound (pi/2) speaks first, naming it as well
    with pytest.raises(ConfigError, match="tilt_max"):
        load_scenario("square", ["controller.position.tilt_max=45"])


def test_the_fields_checked_are_found_by_their_documented_unit():
    """Every section and part is walked; a field's unit is the first [...] of its docstring."""
    found = dict(checked_fields(load_scenario("tunnel")))
    expected = {
        "trajectory.yaw": "rad",
        "estimator.pad_yaw": "rad",  # "... the world frame's yaw [rad]. Roll and pitch ..."
        "controller.position.tilt_max": "rad",  # "[rad] (MPC_TILTMAX_AIR, there in degrees)"
        "world.entrance_yaw": "deg",  # named *_yaw but documented [deg]: its documentation wins
        "failsafe.FD_FAIL_R": "deg",
        "realism.vehicle.pad_tilt_max_deg": "deg",
        "mission.v_max": "speed",
        "controller.position.xy_vel_max": "speed",
        "mission.a_max": "acceleration",
        "controller.geometric.i_max": "acceleration",
    }
    assert {k: found.get(k) for k in expected} == expected
    # an acceleration sigma whose docstring mentions [rad] later, a gain in rad/s^2 per rad, a rate: not angles
    for name in ("estimator.accel_bias_sigma", "controller.geometric.k_R", "rates.physics_hz", "trajectory.hover_s"):
        assert name not in found, name


def test_a_commanders_yaw_is_checked_by_its_name(tmp_path):
    """A commander script's mission items have no docstring on ``yaw``: the name says radians."""
    cfg = load_scenario("vehicle")
    script = cfg.to_dict()["planner"]["script"]
    assert script, "the vehicle scenario plays a script"
    text = load_yaml_text("[[2.0, {command: goto, p_W: [1, 0, 1], yaw: 180}]]", "test")
    with pytest.raises(ConfigError, match=r"yaw = 180 .*degrees"):
        cfg.with_overrides({"planner.script": text})


def test_degree_fields_stay_within_a_full_turn():
    with pytest.raises(ConfigError, match=r"world\.entrance_yaw = 400 .*full turn"):
        load_scenario("tunnel", ["world.entrance_yaw=400"])


def test_values_just_inside_the_bounds_are_accepted_and_just_outside_refused():
    r = reach(presets.cu_astro())
    ok = TrajectoryConfig(yaw=(2 * math.pi - 1e-9, -2 * math.pi + 1e-9, 0, 0, 0))
    assert ok.yaw is not None
    load_scenario("square", {"trajectory.v_max": 0.999 * r.speed, "trajectory.a_max": 0.999 * r.acceleration})
    with pytest.raises(ConfigError, match=r"trajectory\.v_max"):
        load_scenario("square", {"trajectory.v_max": 1.001 * r.speed})
    with pytest.raises(ConfigError, match=r"trajectory\.a_max"):
        load_scenario("square", {"trajectory.a_max": 1.001 * r.acceleration})


def test_the_bounds_follow_the_vehicle_model_worked_by_hand():
    """CU-Astro: k_f 4.97e-7, 3140 rad/s, 0.80 kg, body drag 0.5 rho C_d A on a 216 x 95 mm face."""
    t_max = 4 * 4.97e-7 * 3140.0**2  # 19.60 N
    g, m = 9.80665, 0.80  # standard gravity (QuadrotorParams.gravity)
    r = reach(presets.cu_astro())
    assert r.thrust_to_weight == pytest.approx(t_max / (m * g), rel=1e-12)
    assert r.acceleration == pytest.approx(math.sqrt((t_max / m) ** 2 + g**2), rel=1e-12)  # 26.4 m/s^2
    # level flight: drag c v^2 takes all the thrust left over from the weight
    c = 0.5 * 1.225 * 0.216 * 0.095
    assert r.speed == pytest.approx(math.sqrt(math.sqrt(t_max**2 - (m * g) ** 2) / c), rel=1e-9)  # 37.8 m/s
    # Iris has rotor drag only (linear in speed, at hover rotor speed): a linear balance
    iris = presets.iris()
    w_hover = math.sqrt(1.5 * g / (4 * 5.84e-6))  # hover rotor speed
    t_h = math.sqrt((4 * 5.84e-6 * 1100.0**2) ** 2 - (1.5 * g) ** 2)
    assert reach(iris).speed == pytest.approx(t_h / (4 * w_hover * 1.75e-4), rel=1e-9)
    # both drags at once: the positive root of c v^2 + b v = T_h (numpy's, not ours)
    both = iris.from_dict({**iris.to_dict(), "body_drag": [0.02, 0.03, 0.05]})
    roots = np.roots([0.02, 4 * w_hover * 1.75e-4, -t_h])
    assert reach(both).speed == pytest.approx(float(roots[roots > 0][0]), rel=1e-9)
    # no drag model at all: the fixed ceiling
    bare = iris.from_dict({**iris.to_dict(), "rotor_drag_xy": 0.0})
    assert reach(bare).speed == SPEED_CEILING


def test_a_duplicate_key_names_the_key_and_both_lines():
    with pytest.raises(ConfigError, match=r"here: duplicate key 'b' at line 3 \(first given at line 1\)"):
        load_yaml_text("b: 1\nc: {d: 1}\nb: 2\n", "here")
    with pytest.raises(ConfigError, match=r"duplicate key 'd' at line 3 \(first given at line 2\): c\.d may"):
        load_yaml_text("c:\n  d: 1\n  d: 1\n", "nested")
    # a merge key's values may be overridden, as YAML specifies
    assert load_yaml_text("a: &x {b: 1, c: 2}\nd:\n  <<: *x\n  b: 3\n", "merge")["d"] == {"b": 3, "c": 2}


def test_a_sweep_spec_with_a_duplicate_key_exits_2(tmp_path):
    spec = tmp_path / "sweep.yaml"
    spec.write_text("scenario: square\ngrid:\n  seed: [1, 2]\n  seed: [3]\n", encoding="utf-8")
    done = _cufund("sweep", str(spec), "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert done.returncode == 2 and "duplicate key 'seed' at line 4" in done.stderr, done.stderr
    assert "Traceback" not in done.stderr
    assert "grid.seed may be given only once" in done.stderr


@pytest.mark.parametrize("name", sorted(available_scenarios()))
def test_every_built_in_scenario_is_plausible(name):
    load_scenario(name)
