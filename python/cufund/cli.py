"""The ``cufund`` command line."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

from .config import ConfigError
from .scenario import available_scenarios, load_scenario, run_scenario
from .sensors import allan_report


def _parser() -> argparse.ArgumentParser:
    scenarios = "\n".join(f"  {name:<12} {desc}" for name, desc in available_scenarios().items())
    p = argparse.ArgumentParser(
        prog="cufund", formatter_class=argparse.RawDescriptionHelpFormatter,
        description="cufund: quadrotor simulation and autonomy.",
        epilog=f"built-in scenarios (cufund run NAME):\n{scenarios}\n\nA scenario may also be a YAML file, e.g. a "
               "run folder's config.yaml.")
    sub = p.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run", help="run a scenario and write a run folder",
                         formatter_class=argparse.RawDescriptionHelpFormatter,
                         epilog=f"built-in scenarios:\n{scenarios}")
    run.add_argument("scenario", help="a built-in scenario name or a YAML file")
    run.add_argument("--controller", choices=("pid", "geometric"), help="override the scenario's controller")
    run.add_argument("--out", type=Path, help="run folder (default: runs/<scenario>-<controller>-<time>)")
    run.add_argument("--seed", type=int, help="override the scenario's seed")
    run.add_argument("--viz", action="store_true", help="stream the run live to MeshCat (http on 127.0.0.1)")
    run.add_argument("--no-replay", action="store_true", help="skip replay.html")
    sub.add_parser("list", help="list the built-in scenarios")
    allan = sub.add_parser("allan", help="simulate a static IMU and compare its Allan deviation with its noise model",
                           description="Simulates a static IMU and writes imu.npz (raw samples), allan.png and "
                                       "allan.json (fitted vs configured noise density and bias random walk, per axis).")
    allan_report.add_arguments(allan)
    return p


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.command == "allan":
        try:
            return allan_report.run(args)
        except ValueError as e:
            print(f"cufund: {e}", file=sys.stderr)
            return 2
    if args.command == "list":
        for name, desc in available_scenarios().items():
            print(f"{name:<12} {desc}")
        return 0
    try:
        cfg = load_scenario(args.scenario)
        if args.controller:
            cfg = cfg.replace(controller=dataclasses.replace(cfg.controller, kind=args.controller))
        if args.seed is not None:
            cfg = cfg.replace(seed=args.seed)
    except (ConfigError, OSError) as e:
        print(f"cufund: {e}", file=sys.stderr)
        return 2
    out = args.out or Path("runs") / f"{cfg.name}-{cfg.controller.kind}-{time.strftime('%Y%m%d-%H%M%S')}"
    extra: tuple = ()
    viewer = None
    if args.viz:
        from .scenario import build_reference
        from .viz.live import LiveViewer

        viewer = LiveViewer(cfg.vehicle_params(), build_reference(cfg.trajectory)[0])
        print(f"MeshCat: open {viewer.url}", flush=True)
        extra = (viewer,)
    run = run_scenario(cfg, progress=sys.stderr.isatty() or args.viz, extra_components=extra)
    from .run_folder import write_run_folder

    write_run_folder(run, out, replay=not args.no_replay)
    print(json.dumps(run.metrics, indent=2))
    print(f"run folder: {out.resolve()}")
    if args.viz and sys.stdin.isatty():
        try:
            input("The live view stays up until you press Enter (or Ctrl-C). ")
        except (KeyboardInterrupt, EOFError):
            pass
    if viewer is not None:
        viewer.close()
    return 0 if run.result.status.value == "completed" else 1


if __name__ == "__main__":
    sys.exit(main())
