"""The ``cufund`` command line.

Exit codes: 0 the run completed; 1 it ran but ended otherwise (crashed, diverged, timed out, aborted; the status is
printed); 2 invalid configuration or usage (a message naming the field, no traceback), checked before anything
runs; 130 / 143 ``cufund run`` stopped by SIGINT / SIGTERM (the run folder keeps config.yaml, the closed run.mcap
and metrics.json with status ``interrupted``; no traceback).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import json
import re
import shutil
import signal
import sys
import textwrap
import time
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import NoReturn

from cufund._core import __version__
from cufund.core.config import ConfigError
from cufund.scenarios.schema import available_scenarios, load_scenario, parse_overrides
from cufund.sensors import allan_report

from .arguments import add_overrides

EXIT_COMPLETED, EXIT_NOT_COMPLETED, EXIT_INVALID = 0, 1, 2


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # usage errors exit 2, as argparse does, with our prefix
        self.print_usage(sys.stderr)
        self.exit(EXIT_INVALID, f"cufund: {message}\n")


def _first_sentence(text: str) -> str:
    """The first sentence of ``text`` (all of it when it has one); ``cufund list`` prints the whole."""
    m = re.match(r"(.*?[.!?])(\s|$)", text)
    return m.group(1) if m else text


def _parser() -> argparse.ArgumentParser:
    width = shutil.get_terminal_size((100, 24)).columns - 1
    scenarios = "\n".join(
        _wrapped(name, _first_sentence(desc), width) for name, desc in available_scenarios(whole=True).items()
    )
    p = _Parser(
        prog="cufund",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="cufund: quadrotor simulation and autonomy.",
        epilog=f"built-in scenarios (cufund run NAME; cufund list describes them whole):\n{scenarios}\n\nA scenario "
        "may also be a YAML file, e.g. a run folder's config.yaml.",
    )
    p.add_argument(
        "--version",
        action="version",
        version=f"cufund {__version__}",
        help="print cufund's version (cufund.__version__) and exit",
    )
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    run = sub.add_parser(
        "run",
        help="run a scenario and write a run folder",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=f"built-in scenarios:\n{scenarios}\n\nexit codes: 0 completed, 1 ended otherwise, "
        "2 invalid configuration or usage",
    )
    run.add_argument("scenario", help="a built-in scenario name or a YAML file")
    add_overrides(
        run, help="override a field by its dotted key, e.g. --set controller.kind=geometric --set seed=3 (repeatable)"
    )
    run.add_argument("--controller", help="same as --set controller.kind=NAME")
    run.add_argument("--seed", help="same as --set seed=N")
    run.add_argument("--out", help="run folder (default: runs/<scenario>-<time>)")
    run.add_argument("--viz", action="store_true", help="stream the run live to MeshCat (http on 127.0.0.1)")
    run.add_argument("--no-replay", action="store_true", help="skip replay.html")
    run.add_argument("--no-log", action="store_true", help="skip run.mcap")
    run.add_argument(
        "--json",
        action="store_true",
        help="print the run's metrics as JSON (what metrics.json holds) instead of the summary; the status and the "
        "run folder then go to stderr",
    )
    sub.add_parser("list", help="list the built-in scenarios and registered kinds")
    odo = sub.add_parser(
        "odometry",
        help="run the LiDAR- or visual-inertial odometry open loop on a run.mcap log or a ROS 2 bag",
        description="Runs the LIO on the IMU and LiDAR messages of LOG (with the extrinsics of the "
        "scenario recorded in it; a log flown with estimator kind vio: the VIO on its IMU and stereo images) and "
        "writes odometry.json (errors against the log's ground truth), odometry.png (LIO) and TUM files "
        "(estimate.tum, truth.tum) for evo. LOG may be a ROS 2 bag "
        "folder (sensor_msgs/Imu, sensor_msgs/PointCloud2 or Livox CustomMsg, truth as nav_msgs/Odometry or "
        "geometry_msgs/PoseStamped; docs/guides/ros2.md).",
    )
    odo.add_argument("log", type=Path, help="a run.mcap written by cufund run, or a ROS 2 bag folder")
    for kind in ("imu", "lidar", "truth"):
        odo.add_argument(f"--{kind}-topic", help=f"a ROS 2 bag's {kind} topic (default: found by its type)")
    odo.add_argument(
        "--scenario",
        type=Path,
        help="a scenario YAML whose LIO parameters and sensor mountings to use (default: the one recorded in LOG)",
    )
    odo.add_argument("--out", type=Path, required=True, help="folder for the results")
    allan = sub.add_parser(
        "allan",
        help="simulate a static IMU and compare its Allan deviation with its noise model",
        description="Simulates a static IMU and writes imu.npz (raw samples), allan.png and "
        "allan.json (fitted vs configured noise density and bias random walk, per axis).",
    )
    allan_report.add_arguments(allan)
    from .sweep import cli as sweep_cli

    sweep = sub.add_parser(
        "sweep",
        help="run many variants of a scenario on Dask (local cluster or a scheduler)",
        description="Runs every variant of a sweep file as a Dask task and writes results.parquet, "
        "summary.md, plots/ and each variant's run folder; a re-run resumes. Exit "
        "codes: 0 every variant ran, 1 some failed or interrupted, 2 invalid sweep.",
    )
    sweep_cli.add_arguments(sweep)
    try:
        from . import log_replay
    except ImportError:  # pragma: no cover - the replay viewer is optional at import time
        log_replay = None  # type: ignore[assignment]
    if log_replay is not None:
        rep = sub.add_parser("replay", help="re-open a run.mcap log in the MeshCat viewer")
        log_replay.add_arguments(rep)
    for name, (module, help_text) in _SERVERS.items():
        mod = importlib.import_module(module)
        mod.add_arguments(sub.add_parser(name, help=help_text, description=help_text))
    return p


# Long-running commands, each in its own module: add_arguments(parser) defines its options, run(args) -> exit code.
_SERVERS = {
    "ros2": (
        "cufund.apps.ros2.cli",
        "run a scenario with the ROS 2 bridge over DDS (loopback only unless --expose): ROS 2 nodes read its "
        "sensors and fly it, in lockstep",
    ),
    "train": (
        "cufund.apps.train_cli",
        "train a policy on a cufund task (PPO, skrl on JAX) and export it to ONNX (policy.onnx + policy.yaml "
        "for the controller kind policy)",
    ),
    "dataset": (
        "cufund.apps.dataset_cli",
        "render a labelled detection dataset of a scenario's world (YOLO + COCO, domain randomisation, seeded)",
    ),
    "train-detector": (
        "cufund.apps.train_detector_cli",
        "train a small detector from scratch on `cufund dataset` folders (torch on the CPU) and export it to "
        "ONNX for the onnx_detector",
    ),
    "bag": (
        "cufund.apps.ros2.bag",
        "write a run's log as a ROS 2 bag (rosbag2, sqlite3 or mcap storage) for ros2 bag play, rosbags, Foxglove",
    ),
    "px4-sim": (
        "cufund.apps.mavlink.px4_cli",
        "be PX4's simulator: serve a scenario to px4_sitl over MAVLink (TCP 4560 + "
        "instance, lockstep) or to a flight controller over serial (HITL)",
    ),
    "serve": (
        "cufund.apps.mavlink.serve_cli",
        "fly a scenario in real time as a MAVLink vehicle that ground stations and MAVSDK connect to",
    ),
    "gcs": ("cufund.apps.gcs.cli", "fly a scenario in real time behind a web ground station on 127.0.0.1"),
}


def _wrapped(name: str, text: str, width: int) -> str:
    """``  NAME  text`` with ``text`` wrapped whole (never cut) under a hanging indent."""
    indent = " " * 19
    body = textwrap.fill(
        " ".join(text.split()),
        width=max(width, 60),
        initial_indent=indent,
        subsequent_indent=indent,
        break_on_hyphens=False,
        break_long_words=False,
    )
    return f"  {name:<16} {body[len(indent) :]}" if len(name) <= 16 else f"  {name}\n{body}"


def _list() -> int:
    from cufund.core.registry import GROUPS, available
    from cufund.scenarios.plausibility import reach
    from cufund.vehicle import presets

    width = shutil.get_terminal_size((100, 24)).columns - 1
    print("scenarios (cufund run NAME):")
    for name, desc in available_scenarios(whole=True).items():
        print(_wrapped(name, desc, width))
    print("vehicle presets (vehicle: NAME in a scenario):")
    for name in presets.__all__:
        vp = getattr(presets, name)()
        doc = (getattr(presets, name).__doc__ or "").strip().split("\n\n")[0].replace("``", "")
        r = reach(vp)
        figures = (
            f"[{vp.mass:.3g} kg, thrust-to-weight {r.thrust_to_weight:.3g}, accelerations up to {r.acceleration:.3g} "
            f"m/s^2, speeds up to {r.speed:.3g} m/s]"
        )
        print(_wrapped(name, f"{doc} {figures}", width))
    for group in GROUPS:
        print(f"{group} kinds:")
        for name, kind in sorted(available(group).items()):
            print(_wrapped(name, kind.doc, width))
    return EXIT_COMPLETED


@contextlib.contextmanager
def _interruptible() -> Iterator[None]:
    """SIGINT and SIGTERM raise :class:`RunInterrupted` in the main thread (the run folder is finished, then the
    command exits 128 + the signal); a second signal while that cleanup runs is ignored (SIGKILL still works)."""
    from cufund.scenarios.run_folder import RunInterrupted

    def stop(signum: int, frame: object) -> None:
        for s in (signal.SIGINT, signal.SIGTERM):
            signal.signal(s, signal.SIG_IGN)
        RunInterrupted.raise_for(signum)

    RunInterrupted.received = None
    previous = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        RunInterrupted.received = None


def _run(args: argparse.Namespace) -> int:
    from cufund.scenarios.run_folder import RunInterrupted

    with _interruptible():
        try:
            return _run_scenario(args)
        except BaseException as exc:
            signum = exc.signum if isinstance(exc, RunInterrupted) else RunInterrupted.received
            if signum is None:
                raise
            print(
                f"cufund: interrupted by {signal.Signals(signum).name}; the run folder holds what was run up to then",
                file=sys.stderr,
            )
            return 128 + signum


def _run_scenario(args: argparse.Namespace) -> int:
    from cufund.scenarios.build import build_simulation, out_dir_problem

    try:
        overrides = parse_overrides(args.overrides)
        if args.controller is not None:
            overrides["controller.kind"] = args.controller
        if args.seed is not None:
            overrides.update(parse_overrides([f"seed={args.seed}"]))
        cfg = load_scenario(args.scenario, overrides)
        if args.out is not None and not args.out.strip():
            raise ConfigError("--out must name a folder, got an empty string")
        out = Path(args.out) if args.out is not None else Path("runs") / f"{cfg.name}-{time.strftime('%Y%m%d-%H%M%S')}"
        problem = out_dir_problem(out)
        if problem:
            raise ConfigError(problem)
        if cfg.vehicles:  # a fleet: several vehicles in one world (docs/guides/fleets.md)
            from cufund.scenarios.fleet_folder import fleet_summary
            from cufund.scenarios.run_folder import run_fleet_into_folder

            fleet_run = run_fleet_into_folder(cfg, out, log=not args.no_log, replay=not args.no_replay)
            print(json.dumps(fleet_run.metrics, indent=2, default=str) if args.json else fleet_summary(fleet_run, out))
            return EXIT_COMPLETED if fleet_run.status == "completed" else EXIT_NOT_COMPLETED
        built = build_simulation(cfg)  # the whole graph validated before anything runs
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise ConfigError(f"--out {out}: cannot create the folder: {e.strerror or e}") from None
    except (ConfigError, OSError) as e:
        print(f"cufund: {e}", file=sys.stderr)
        return EXIT_INVALID
    from cufund.scenarios.run_folder import run_into_folder

    viewer = None
    if args.viz:
        from cufund.viz.live import LiveViewer

        viewer = LiveViewer(cfg.vehicle_params(), built.context.reference)
        print(f"MeshCat: open {viewer.url}", flush=True)
        built.simulator.add(viewer)
    run = run_into_folder(
        built, out, log=not args.no_log, replay=not args.no_replay, progress=sys.stderr.isatty() or args.viz
    )
    status = run.result.status.value
    if args.json:
        print(json.dumps(run.metrics, indent=2, default=str))
        print(f"status: {status} ({run.result.message})\nrun folder: {out.resolve()}", file=sys.stderr)
    else:
        from .run_summary import summary

        print(summary(run.metrics, out, cfg.mission.kind if cfg.mission is not None else None))
    if args.viz and sys.stdin.isatty():
        try:
            input("The live view stays up until you press Enter (or Ctrl-C). ")
        except (KeyboardInterrupt, EOFError):
            pass
    if viewer is not None:
        viewer.close()
    return EXIT_COMPLETED if status == "completed" else EXIT_NOT_COMPLETED


def _odometry(args: argparse.Namespace) -> int:
    from cufund.core.config import load_yaml_text
    from cufund.scenarios.build import ScenarioBuildContext, out_dir_problem
    from cufund.scenarios.schema import ScenarioConfig

    try:
        from cufund.estimation.kinds import lio_params
        from cufund.estimation.offline import run_on_log
        from cufund.estimation.params import LioParams
        from cufund.logs.mcap_reader import log_metadata

        problem = out_dir_problem(args.out)
        if problem:
            raise ConfigError(problem)
        from cufund.logs.rosbag2_reader import bag_custom_data, is_rosbag2, pick_topic

        bag = is_rosbag2(args.log)
        meta = {k.removeprefix("cufund."): v for k, v in bag_custom_data(args.log).items()} if bag else None
        meta = meta if meta is not None else log_metadata(args.log)
        if args.scenario is not None:  # the mountings of a user's own drone, for a bag that does not carry them
            meta["config"] = args.scenario.read_text()
        params, imu, lidar = LioParams(), "/sensors/imu", "/sensors/lidar"
        if "config" in meta:  # the scenario the log was recorded with: its extrinsics and IMU
            cfg = ScenarioConfig.from_dict(load_yaml_text(meta["config"], f"{args.log}: its recorded config"))
            if cfg.estimator is not None and cfg.estimator.kind == "vio" and bag:
                raise ConfigError(
                    f"{args.log}: a run flown on the VIO; cufund odometry reruns it on the run's run.mcap (a ROS 2 "
                    "bag's sensor_msgs/Image are not read)"
                )
            if cfg.estimator is not None and cfg.estimator.kind == "vio":  # a log flown on the VIO
                from cufund.estimation.kinds import vio_params
                from cufund.estimation.vio_offline import run_vio_on_log

                vp, imu_spec, cams = vio_params(cfg.estimator.params, ScenarioBuildContext(cfg))
                figures = run_vio_on_log(args.log, vp, args.out, imu_spec.topic, tuple(cams))
                print(json.dumps(figures, indent=2))
                print(f"odometry folder: {args.out.resolve()}")
                return EXIT_COMPLETED
            if cfg.estimator is not None and cfg.estimator.kind == "lio":
                params = cfg.estimator.params
            params, imu_spec, lidar_spec = lio_params(params, ScenarioBuildContext(cfg))
            imu, lidar = imu_spec.topic, lidar_spec.topic
        truth = "/truth/odometry"
        if bag:  # a cufund bag has the IMU as sensor_msgs/Imu on <imu>/ros and the truth pose on <truth>/pose
            imu = args.imu_topic or pick_topic(args.log, "Imu", [f"{imu}/ros", imu], "--imu-topic")
            lidar = args.lidar_topic or pick_topic(args.log, "PointCloud", [lidar], "--lidar-topic")
            truth = args.truth_topic or pick_topic(args.log, "Pose", [f"{truth}/pose", truth], "--truth-topic")
        figures = run_on_log(args.log, params, args.out, imu_topic=imu, lidar_topic=lidar, truth_topic=truth)
    except (ConfigError, ValueError, OSError) as e:
        print(f"cufund: {e}", file=sys.stderr)
        return EXIT_INVALID
    print(json.dumps(figures, indent=2))
    print(f"odometry folder: {args.out.resolve()}")
    return EXIT_COMPLETED


def _one_line_warning(
    message: Warning | str, category: type[Warning], filename: str, lineno: int, line: str | None = None
) -> str:
    return f"cufund: warning: {message}\n"


def main(argv: list[str] | None = None) -> int:
    warnings.formatwarning = _one_line_warning  # e.g. a truncated log: one line, not a source excerpt
    args = _parser().parse_args(argv)
    if args.command == "allan":
        try:
            return allan_report.run(args)
        except ValueError as e:
            print(f"cufund: {e}", file=sys.stderr)
            return EXIT_INVALID
    if args.command == "sweep":
        from .sweep import cli as sweep_cli

        return sweep_cli.run_cli(args)
    if args.command == "list":
        return _list()
    if args.command in _SERVERS:
        return importlib.import_module(_SERVERS[args.command][0]).run(args)
    if args.command in ("odometry", "replay"):
        try:
            return _odometry(args) if args.command == "odometry" else _replay(args)
        except KeyboardInterrupt:  # Ctrl-C: a message and 130, not a traceback
            print(f"cufund {args.command}: interrupted", file=sys.stderr)
            return 128 + signal.SIGINT
    return _run(args)


def _replay(args: argparse.Namespace) -> int:
    from . import log_replay

    try:
        return log_replay.run(args)
    except (ConfigError, ValueError, OSError) as e:
        print(f"cufund: {e}", file=sys.stderr)
        return EXIT_INVALID


if __name__ == "__main__":
    sys.exit(main())
