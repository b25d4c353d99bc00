"""Scenarios as pipelines: validation at load (each bad file exits 2 naming the field), dotted overrides, the kind
registry (Python and entry points), pickling."""

import dataclasses
import pickle
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import cufund
from cufund import ConfigError, ScenarioConfig, available_scenarios, load_scenario
from cufund.apps.cli import main
from cufund.core.registry import Kind, available, lookup, register, unregister

GOOD = """
name: t
world: imav2025_tunnel
sensors:
  imu: {kind: icm42688p, T_BI: {p: [0, 0, 0.01], q: [1, 0, 0, 0]}}
  lidar: {kind: mid360, T_BL: {p: [0, 0, 0.08], q: [1, 0, 0, 0]}}
  pose: {kind: pose, rate_hz: 10}
estimator: {kind: imu_propagator}
mapper: {kind: esdf, resolution: 0.2}
start_p_W: [-3, 0, 0]
trajectory: {waypoints: [[-3, 0, 1.2], [-2, 0, 1.2]]}
duration: 5
"""

# (yaml text, the text the message must contain) -- each must exit 2 before the run starts
INVALID = [
    ("controller: {kind: lqr}", "controller.kind must be one of geometric, pid, policy, ros2_external, got 'lqr'"),
    ("estimator: {kind: ekf9000}", "estimator.kind must be one of"),
    ("world: {kind: moon}", "world.kind must be one of"),
    ("planner: teleport", "planner.kind must be one of"),
    ("mapper: {kind: octomap}", "mapper.kind must be one of"),
    ("sensors: {imu: {kind: mpu6050}}", "sensors.imu.kind must be one of"),
    ("controller: {position: {xy_p: 1}}", "missing key 'kind' in controller"),
    ("duraton: 3", "unknown key 'duraton' in scenario"),
    ("controller: {kind: pid, position: {xy_pp: 1}}", "unknown key 'xy_pp' in controller.position"),
    ("controller: {kind: pid, gains: 1}", "unknown key 'gains' in controller (kind pid)"),
    ("sensors: {gps: {kind: ublox_m8n, rate: 5}}", "unknown key 'rate' in sensors.gps"),
    ("controller: {kind: pid, rate: {roll_p: -1}}", "RateControlParams.roll_p must be a finite number >= 0"),
    ("rates: {physics_hz: 0}", "rates.physics_hz must be a finite number > 0"),
    ("rates: {rate_hz: 0}", "rates.rate_hz must be a finite number > 0"),
    ("rates: {position_hz: .nan}", "rates.position_hz must be a finite number > 0"),
    ("rates: {attitude_hz: -5}", "rates.attitude_hz must be a finite number > 0"),
    ("rates: {trajectory_hz: fast}", "rates.trajectory_hz must be a finite number > 0"),
    ("duration: .inf", "duration must be a finite number > 0"),
    ("duration: long", "duration must be a finite number > 0"),
    ("seed: -1", "seed must be an integer"),
    ("seed: 1.5", "seed must be an integer"),
    ("name: 5", "name must be a non-empty string"),
    ("vehicle: bebop", "vehicle must be one of crazyflie, iris, cu_astro"),
    ("vehicle: {mass: 1.0}", "vehicle: "),
    ("trajectory: {waypoints: [[0, 0, 1]]}", "trajectory.waypoints must be a list of at least 2"),
    ("trajectory: {waypoints: [[0, 0, 1], [1, 0, .nan]]}", "trajectory.waypoints must be a list of at least 2"),
    ("trajectory: {v_max: 0}", "trajectory.v_max must be a number > 0"),
    ("trajectory: {yaw: [.nan, 0, 0, 0, 0]}", "trajectory.yaw must have one finite angle per waypoint"),
    ("sensors: {imu: {kind: icm42688p, T_BI: {p: [0, 0], q: [1, 0, 0, 0]}}}", "sensors.imu.T_BI"),
    (
        "sensors: {imu: {kind: icm42688p, T_BI: {p: [0, 0, 0], q: [1, 1, 0, 0]}}}",
        "sensors.imu.T_BI.q must be a unit quaternion",
    ),
    ("sensors: {imu: {kind: icm42688p, T_BL: {p: [0, 0, 0]}}}", "sensors.imu.T_BL: a imu sensor's extrinsic is T_BI"),
    ("sensors: {imu: {kind: icm42688p, T_BI: {p: [0, 0, 0], r: [1, 0, 0, 0]}}}", "unknown key 'r' in sensors.imu.T_BI"),
    ("sensors: {imu: {kind: icm42688p, rate_hz: 0}}", "rate_hz must be between 100 and 1000"),
    ("sensors: {imu: {kind: icm42688p, latency_s: -0.1}}", "sensors.imu.latency_s must be a number of seconds"),
    ("sensors: {lidar: {kind: mid360}}", "sensors.lidar needs a world"),
    ("world: empty\nsensors: {lidar: {kind: mid360, range_noise_std: .nan}}", "LidarSensorParams.range_noise_std"),
    ("sensors: {pose: {kind: pose}}\nestimator: imu_propagator", "estimator needs a imu sensor"),
    ("world: empty\nmapper: esdf", "mapper.lidar needs a lidar sensor"),
    (
        "sensors: {imu: icm42688p, pose: pose}\nestimator: {kind: imu_propagator, accel_noise_density: .nan}",
        "estimator.accel_noise_density must be a finite number",
    ),
    ("sensors: {imu: icm42688p, pose: {kind: pose, topic: /sensors/imu}}", "two sensors publish on /sensors/imu"),
    ("sensors: {imu: {kind: icm42688p, topic: no_slash}}", "sensors.imu.topic: a topic name must be an absolute path"),
    ("sensors: [imu]", "sensors must be a mapping"),
    ("sensors: {'bad name': icm42688p}", "a sensor name must be an identifier"),
    ("world: {kind: forest, n_trees: -3}", "world.n_trees must be an integer >= 0"),
    ("world: {kind: file, path: nowhere.yaml}", "world.path: no world file at"),
    ("log: {mcap: maybe}", "log.mcap must be true or false"),
    ("start_p_W: [0, 0, -1]", "start_p_W must be 3 finite numbers"),
    ("[1, 2, 3]", "a scenario must be a mapping"),
    ("controller: {kind: pid\n", "invalid YAML"),
]


@pytest.mark.parametrize("text, message", INVALID, ids=[f"bad{i}" for i in range(len(INVALID))])
def test_invalid_scenario_files_exit_2_naming_the_field(tmp_path, capsys, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text + "\n")
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert message in err, err
    assert "Traceback" not in err
    assert not (tmp_path / "out").exists()  # nothing ran


def test_there_are_at_least_30_invalid_files():
    assert len(INVALID) >= 30


def test_a_good_pipeline_loads_and_round_trips(tmp_path):
    path = tmp_path / "good.yaml"
    path.write_text(GOOD)
    cfg = load_scenario(path)
    assert cfg.sensors["lidar"].extrinsic.t == (0.0, 0.0, 0.08)
    assert cfg.sensors["imu"].topic == "/sensors/imu" and cfg.sensors["imu"].topic.type is cufund.core.messages.Imu
    assert ScenarioConfig.from_dict(cfg.to_dict()) == cfg
    assert pickle.loads(pickle.dumps(cfg)) == cfg
    from cufund.scenarios.build import build_simulation

    built = build_simulation(cfg)  # the whole graph wires up
    assert {type(c).__name__ for c in built.simulator.components} >= {
        "ImuSensor",
        "LidarComponent",
        "PoseSensor",
        "ImuPropagator",
        "EsdfMapper",
        "RateController",
    }


def test_unsatisfied_input_names_the_topic(tmp_path):
    class NeedsMap(cufund.Planner):
        name = "map_planner"
        reads = (cufund.Topics.ESDF_MAP,)

        def update(self, t, state, bus):
            pass

    register(Kind("planner", "needs_map", NoParams, lambda p, ctx: [NeedsMap()]))
    try:
        path = tmp_path / "s.yaml"
        path.write_text("planner: needs_map\n")
        with pytest.raises(ConfigError, match="map_planner needs /map/esdf; nothing publishes it"):
            from cufund.scenarios.build import build_simulation

            build_simulation(load_scenario(path))
        assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 2
    finally:
        unregister("planner", "needs_map")


@dataclasses.dataclass(frozen=True)
class NoParams:
    pass


def test_overrides_from_python_and_the_cli(tmp_path, capsys):
    cfg = load_scenario("square", {"controller.kind": "geometric", "seed": 3, "trajectory.v_max": 0.5})
    assert (cfg.controller.kind, cfg.seed, cfg.trajectory.v_max) == ("geometric", 3, 0.5)
    assert cfg.controller.params == load_scenario("square").controller.params  # the gains stay
    cfg = load_scenario("square_sensors", ["sensors.imu.rate_hz=400", "world.seed=4", "world.kind=forest"])
    assert cfg.sensors["imu"].params.rate_hz == 400 and cfg.sensors["imu"].kind == "icm42688p"
    assert cfg.world.kind == "forest" and cfg.world.params.seed == 4
    with pytest.raises(ConfigError, match="unknown key 'xy_pp' in controller.position"):
        load_scenario("square", ["controller.position.xy_pp=1"])
    with pytest.raises(ConfigError, match="--set takes KEY=VALUE"):
        load_scenario("square", ["controller.kind"])
    heavy = load_scenario("square", ["vehicle.mass=1"])  # a preset name becomes {preset: cu_astro, mass: 1}
    assert heavy.vehicle == {"preset": "cu_astro", "mass": 1}
    assert heavy.vehicle_params().k_f == cufund.presets.cu_astro().k_f
    assert main(["run", "square", "--set", "controller.kind=lqr"]) == 2
    assert "controller.kind must be one of" in capsys.readouterr().err
    assert (
        main(
            [
                "run",
                "square",
                "--set",
                "duration=0.5",
                "--set",
                "seed=2",
                "--out",
                str(tmp_path / "o"),
                "--no-replay",
                "--no-log",
            ]
        )
        == 1
    )  # ran, did not land in 0.5 s: timeout
    out = capsys.readouterr().out
    assert "status: timeout" in out
    again = load_scenario(tmp_path / "o" / "config.yaml")
    assert (again.duration, again.seed) == (0.5, 2)


def test_out_is_checked_before_the_run(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["run", "square", "--out", str(f)]) == 2
    assert "exists and is not a folder" in capsys.readouterr().err
    assert main(["run", "square", "--out", str(f / "sub")]) == 2


def test_unknown_scenario_and_usage_errors_exit_2(capsys):
    assert main(["run", "circle"]) == 2
    err = capsys.readouterr().err
    assert "unknown scenario 'circle'; built-in: " in err and " square," in err
    with pytest.raises(SystemExit) as e:
        main(["run"])
    assert e.value.code == 2
    with pytest.raises(SystemExit) as e:
        main(["fly", "square"])
    assert e.value.code == 2


def test_cli_exit_2_has_no_traceback_in_a_real_process(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("rates: {physics_hz: .nan}\n")
    exe = Path(sys.executable).parent / "cufund"
    r = subprocess.run([str(exe), "run", str(bad)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "rates.physics_hz must be a finite number > 0" in r.stderr
    assert "Traceback" not in r.stderr


def test_registry_from_python_and_entry_points(tmp_path):
    kind = Kind("mission", "noop", NoParams, lambda p, ctx: [], doc="does nothing")
    register(kind)
    try:
        assert lookup("mission", "noop") is kind
        with pytest.raises(ValueError, match="registered already"):
            register(Kind("mission", "noop", NoParams, lambda p, ctx: []))
        cfg = ScenarioConfig.from_dict({"mission": "noop"})
        assert cfg.mission.kind == "noop"
    finally:
        unregister("mission", "noop")
    with pytest.raises(ConfigError, match="mission.kind must be one of"):
        ScenarioConfig.from_dict({"mission": "noop"})
    # an installed package adds kinds through the entry-point group "cufund.kinds"
    pkg = tmp_path / "site"
    (pkg / "myplugin").mkdir(parents=True)
    (pkg / "myplugin" / "__init__.py").write_text(
        textwrap.dedent("""
        import dataclasses
        from cufund.core.registry import Kind

        @dataclasses.dataclass(frozen=True)
        class P:
            gain: float = 1.0

        KINDS = [Kind("estimator", "plugin_ekf", P, lambda p, ctx: [], doc="from a plug-in")]
    """)
    )
    dist = pkg / "myplugin-1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: myplugin\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("[cufund.kinds]\nplugin = myplugin:KINDS\n")
    code = (
        "import cufund.core.registry as r; k = r.lookup('estimator', 'plugin_ekf'); "
        "print(k.doc, r.ScenarioConfig if False else '', k.parse({'gain': 2.0}, 'estimator').gain)"
    )
    r = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        env={"PYTHONPATH": str(pkg), "PATH": "/usr/bin:/bin"},
    )
    assert r.returncode == 0, r.stderr
    assert "from a plug-in" in r.stdout and "2.0" in r.stdout


def test_builtin_kinds_are_listed(capsys):
    assert {"pid", "geometric"} <= set(available("controller"))
    assert {"icm42688p", "mid360", "pose", "d435_depth"} <= set(available("sensor"))
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "square_mocap" in out and "imu_propagator" in out


def test_square_is_listed_and_loads():
    assert {"square", "square_sensors", "square_mocap"} <= set(available_scenarios())
    cfg = load_scenario("square")
    assert cfg.vehicle == "cu_astro" and cfg.controller.kind == "pid" and cfg.rates.physics_hz == 1000.0
    assert ScenarioConfig.from_dict(cfg.to_dict()) == cfg


def test_the_run_summary_and_the_config_pickle():
    from cufund.scenarios.build import RunSummary, run_scenario

    run = run_scenario(load_scenario("square", {"duration": 1.0}))
    summary = run.summary({"metrics": "metrics.json"})
    again = pickle.loads(pickle.dumps(summary))
    assert isinstance(again, RunSummary) and again == summary
    assert again.status == "timeout" and again.metrics["sim_time_s"] == 1.0
    cfg = load_scenario("square_mocap", {"seed": 5})
    assert pickle.loads(pickle.dumps(cfg)) == cfg


def _distance_to_polyline(q, corners):
    d = []
    for a, b in zip(corners[:-1], corners[1:], strict=True):
        ab = b - a
        t = np.clip(((q - a) @ ab) / (ab @ ab), 0.0, 1.0)
        d.append(np.linalg.norm(q - (a + np.outer(t, ab)), axis=1))
    return np.min(d, axis=0)


def test_a_trajectory_corridor_keeps_the_square_within_its_half_width():
    from cufund.scenarios.build import build_simulation

    corners = np.array([[0, 0, 1.5], [1, 0, 1.5], [1, 1, 1.5], [0, 1, 1.5], [0, 0, 1.5]], dtype=float)
    plain = build_simulation(load_scenario("square")).context.tracking_path
    tube = build_simulation(load_scenario("square", ["trajectory.corridor=0.15"])).context.tracking_path
    for path, bound in ((plain, None), (tube, 0.15)):
        p = path.sample(np.linspace(path.t_knots[0], path.t_end, 4000)).p_W
        worst = _distance_to_polyline(p, corners).max()
        if bound is None:
            assert worst > 0.3  # the plain min-snap square bulges out
        else:
            assert worst <= bound
    with pytest.raises(ConfigError, match="trajectory.corridor must be a half-width > 0"):
        load_scenario("square", ["trajectory.corridor=-1"])


def test_tunnel_course_world_kind_follows_world_seed():
    from cufund.scenarios.build import build_simulation

    a = build_simulation(load_scenario("square", ["world.kind=tunnel_course", "world.seed=2", "start_p_W=[-20, 0, 0]"]))
    b = build_simulation(
        load_scenario("square", {"world": {"kind": "tunnel_course", "seed": 2}, "start_p_W": [-20, 0, 0]})
    )
    c = build_simulation(
        load_scenario("square", {"world": {"kind": "tunnel_course", "seed": 5}, "start_p_W": [-20, 0, 0]})
    )
    verts = [np.concatenate([o.vertices for o in x.context.world.objects]) for x in (a, b, c)]
    assert np.array_equal(verts[0], verts[1]) and not np.array_equal(verts[0], verts[2])


def test_an_empty_out_is_refused_not_the_current_folder(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "square", "--out", ""]) == 2
    assert "--out must name a folder" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_an_out_that_cannot_be_created_exits_2(capsys):
    assert main(["run", "square", "--out", "/proc/nope/run"]) == 2
    assert "--out /proc/nope/run: cannot create the folder" in capsys.readouterr().err
