"""Every rate and size in a scenario has an upper bound with a clear error (a 1e9 Hz LiDAR pose rate filled 937 MB
of log in a minute), and YAML numbers like 1e9 are numbers (YAML 1.1 read them as strings: "got '1e9'"). Scenario
files are plain data: no ``!!python`` tags."""

from __future__ import annotations

import dataclasses
import typing

import pytest

from cufund.apps.cli import main
from cufund.core.config import ConfigError, load_yaml, load_yaml_text
from cufund.core.registry import GROUPS, available
from cufund.scenarios.schema import load_scenario, parse_overrides

HUGE_INT = 10**12
HUGE = 1e12

# (scenario, dotted key, what the error says)
BOUNDED = [
    ("square_lio", "sensors.lidar.pose_rate_hz", "pose_rate_hz must be at most 10000"),
    ("square_lio", "sensors.lidar.range_max", "range_max must be at most 10000"),
    ("square_lio", "estimator.init_duration_s", "init_duration_s must be at most 3600"),
    ("square_lio", "estimator.map_max_voxels", "map_max_voxels must be at most 1e+08"),
    ("square_lio", "estimator.map_points_per_voxel", "map_points_per_voxel must be at most 1000"),
    ("square_lio", "estimator.max_iterations", "max_iterations must be at most 1000"),
    ("square_lio", "estimator.max_refits", "max_refits must be at most 100"),
    ("square_lio", "estimator.smoother_iterations", "smoother_iterations must be at most 100"),
    ("square_lio", "rates.physics_hz", "rates.physics_hz must be at most 1e6"),
    ("square_lio", "duration", "duration must be at most 1e6"),
    ("forest", "mapper.rate_hz", "mapper.rate_hz must be at most 1000"),
    ("forest", "mapper.max_range", "mapper.max_range must be at most 1000"),
    ("forest", "planner.rate_hz", "planner.rate_hz must be at most 1000"),
    ("forest", "planner.horizon", "planner.horizon must be at most 1000"),
    ("forest", "planner.max_iterations", "planner.max_iterations must be at most 10000"),
    ("forest", "world.n_trees", "world.n_trees must be at most 100000"),
    ("forest", "world.size", "world.size must be at most 10000"),
    ("tunnel", "mission.rate_hz", "mission.rate_hz must be at most 1000"),
    ("tunnel", "mission.frames", "mission.frames must be at most 1000"),
    ("tunnel", "world.n_frames", "n_frames must be at most 1000"),
    ("tunnel", "world.max_attempts", "max_attempts must be at most 100000"),
    ("vehicle", "planner.rate_hz", "planner.rate_hz must be at most 10000"),
    ("vehicle", "planner.status_hz", "planner.status_hz must be at most 1000"),
]

INTEGER_FIELDS = {
    "map_max_voxels",
    "map_points_per_voxel",
    "max_iterations",
    "max_refits",
    "smoother_iterations",
    "n_trees",
    "frames",
    "n_frames",
    "max_attempts",
}


@pytest.mark.parametrize("scenario, key, message", BOUNDED)
def test_a_huge_rate_or_size_is_refused_by_name(scenario, key, message):
    huge = HUGE_INT if key.rsplit(".", 1)[-1] in INTEGER_FIELDS else HUGE
    with pytest.raises(ConfigError, match=message.replace("+", r"\+")):
        load_scenario(scenario, {key: huge})
    load_scenario(scenario, {})  # the scenario itself is valid: the bound is what failed


def _params_classes() -> list[tuple[str, type]]:
    """Every params dataclass a scenario can reach through a registered kind (nested ones too)."""
    out, todo, seen = (
        [],
        [(f"{group}:{name}", kind.params) for group in GROUPS for name, kind in sorted(available(group).items())],
        set(),
    )
    while todo:
        where, cls = todo.pop()
        if cls in seen or not dataclasses.is_dataclass(cls):
            continue
        seen.add(cls)
        out.append((where, cls))
        try:
            hints = typing.get_type_hints(cls)
        except Exception:  # forward references to other layers: the defaults tell
            hints = {}
        try:
            defaults = cls()
        except Exception:  # a params class with required fields (a world file's path)
            continue
        for f in dataclasses.fields(cls):
            value = getattr(defaults, f.name)
            nested = type(value) if dataclasses.is_dataclass(value) else hints.get(f.name)
            if isinstance(nested, type) and dataclasses.is_dataclass(nested):
                todo.append((f"{where}.{f.name}", nested))
    return out


def _rate_fields() -> list[tuple[str, type, str]]:
    """Every event rate [Hz] of every kind's params (a filter's cut-off frequency is not an event rate)."""
    return [
        (where, cls, f.name)
        for where, cls in _params_classes()
        for f in dataclasses.fields(cls)
        if f.name.endswith("_hz") and "cutoff" not in f.name
    ]


def test_the_audit_sees_the_rates():
    names = {f"{cls.__name__}.{name}" for _, cls, name in _rate_fields()}
    assert {
        "LidarSensorParams.pose_rate_hz",
        "EsdfMapperParams.rate_hz",
        "CommanderParams.status_hz",
        "ImuParams.rate_hz",
        "GpsParams.rate_hz",
    } <= names


@pytest.mark.parametrize("where, cls, name", _rate_fields(), ids=lambda v: v if isinstance(v, str) else "")
def test_every_rate_of_every_kind_has_an_upper_bound(where, cls, name):
    defaults = cls()
    with pytest.raises((ConfigError, ValueError), match=name):
        dataclasses.replace(defaults, **{name: HUGE})


def test_cli_refuses_the_probe_s_lidar_rate_before_running(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", "square_lio", "--set", "sensors.lidar.pose_rate_hz=1e9", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "pose_rate_hz must be at most 10000, got 1000000000.0" in err and "Traceback" not in err
    assert not out.exists()


@pytest.mark.parametrize(
    "text, value",
    [
        ("1e9", 1e9),
        ("1e-3", 1e-3),
        ("-2E5", -2e5),
        ("1.5e3", 1500.0),
        (".5e1", 5.0),
        ("+3e2", 300.0),
        ("1.0e+9", 1e9),
        ("12", 12),
        ("1e", "1e"),
        ("e9", "e9"),
        ("0x10", 16),
    ],
)
def test_yaml_exponent_numbers_are_numbers(text, value):
    parsed = parse_overrides([f"duration={text}"])["duration"]
    assert parsed == value and type(parsed) is type(value)
    assert load_yaml_text(f"x: {text}", "test") == {"x": value}


def test_set_duration_1e9_names_the_bound_not_a_string(capsys):
    assert main(["run", "square", "--set", "duration=1e9"]) == 2
    err = capsys.readouterr().err
    assert "duration must be at most 1e6 s, got 1000000000.0" in err and "'1e9'" not in err


def test_scenario_file_numbers_and_no_python_tags(tmp_path):
    good = tmp_path / "s.yaml"
    good.write_text("name: s\nduration: 2e1\n")
    assert load_yaml(good) == {"name": "s", "duration": 20.0}
    marker = tmp_path / "marker"
    for tag in ("!!python/object/apply:os.system", "!!python/object/new:subprocess.Popen"):
        bad = tmp_path / "bad.yaml"
        bad.write_text(f"name: {tag} [[touch, {marker}]]\n")
        with pytest.raises(ConfigError, match="bad.yaml: invalid YAML"):
            load_yaml(bad)
        with pytest.raises(ConfigError, match="invalid YAML"):
            load_scenario(str(bad))
    with pytest.raises(ConfigError, match="--set name: invalid YAML"):
        parse_overrides([f"name=!!python/object/apply:os.system [touch {marker}]"])
    assert not marker.exists()


def test_set_values_are_bounded_like_files():
    laughs = "[" + ",".join(["&a [1,1,1,1,1,1,1,1,1,1]"] + ["*a"] * 1200) + "]"
    with pytest.raises(ConfigError, match="--set x: more than yaml_max_aliases"):
        parse_overrides([f"x={laughs}"])


@pytest.mark.parametrize(
    "scenario, key, value, part",
    [
        ("tunnel", "world.resolution", 1e-3, "world (tunnel_course)"),
        ("forest_global", "planner", {"kind": "global_known_map", "resolution": 2e-3}, "planner (global_known_map)"),
    ],
)
def test_a_known_geometry_grid_past_the_voxel_limit_is_refused_before_allocating(scenario, key, value, part):
    """A fine resolution over the course or the planner's box asked numpy for 20-205 GiB; now the voxel limit."""
    import re

    from cufund.scenarios.build import build_simulation

    with pytest.raises(ConfigError, match=re.escape(part) + r": resolution .* voxels, more than grid_max_voxels"):
        build_simulation(load_scenario(scenario, {key: value}))
