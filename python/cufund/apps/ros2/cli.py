"""``cufund ros2 SCENARIO``: run a scenario with the ROS 2 bridge (its ``ros2:`` key, or the defaults) and write a
run folder, as ``cufund run`` does. Exit codes: 0 completed, 1 ended otherwise (a lockstep node that did not answer
included), 2 invalid configuration or usage."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from cufund.apps.arguments import add_overrides
from cufund.core.config import ConfigError

__all__ = ["add_arguments", "run"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", help="a built-in scenario name or a YAML file")
    add_overrides(p, help="override a field by its dotted key, e.g. --set seed=3 (repeatable)")
    p.add_argument(
        "--domain-id",
        type=int,
        help="the DDS domain; default the scenario's ros2.domain_id, else $ROS_DOMAIN_ID, else 0",
    )
    p.add_argument(
        "--lockstep-node",
        action="append",
        default=None,
        help="a node that answers each step on /cufund/step_ack (repeatable); simulated time waits for it",
    )
    p.add_argument("--no-lockstep", action="store_true", help="do not wait for the nodes")
    p.add_argument("--realtime", action="store_true", help="pace simulated time to the wall clock")
    p.add_argument("--timeout", type=float, help="seconds a lockstep node may take to answer (default 10)")
    p.add_argument(
        "--expose",
        action="store_true",
        help="let DDS leave this host (every interface, multicast discovery); default: loopback only",
    )
    p.add_argument("--out", help="run folder (default: runs/<scenario>-ros2-<time>)")
    p.add_argument("--no-log", action="store_true", help="skip run.mcap")


def run(args: argparse.Namespace) -> int:
    from cufund.scenarios.build import build_simulation, out_dir_problem
    from cufund.scenarios.schema import ScenarioConfig, load_scenario, parse_overrides

    from .bridge import Ros2Timeout

    try:
        cfg = load_scenario(args.scenario, parse_overrides(args.overrides))
        data = cfg.to_dict()
        ros2 = dict(data.get("ros2") or {})
        if args.domain_id is not None:
            ros2["domain_id"] = args.domain_id
        elif "domain_id" not in ros2 and os.environ.get("ROS_DOMAIN_ID", "").strip():
            env = os.environ["ROS_DOMAIN_ID"].strip()
            if not env.isdigit():
                raise ConfigError(f"ROS_DOMAIN_ID must be an integer in [0, 232], got {env!r}")
            ros2["domain_id"] = int(env)
        if args.lockstep_node:
            ros2["lockstep_nodes"] = list(args.lockstep_node)
        if args.no_lockstep:
            ros2["lockstep"] = False
        if args.realtime:
            ros2["realtime"] = True
        if args.expose:
            ros2["expose"] = True
        if args.timeout is not None:
            ros2["timeout_s"] = args.timeout
        data["ros2"] = ros2
        cfg = ScenarioConfig.from_dict(data, cfg.base_dir)
        out = Path(args.out) if args.out else Path("runs") / f"{cfg.name}-ros2-{time.strftime('%Y%m%d-%H%M%S')}"
        problem = out_dir_problem(out)
        if problem:
            raise ConfigError(problem)
        built = build_simulation(cfg)
        out.mkdir(parents=True, exist_ok=True)
    except (ConfigError, OSError, ValueError) as e:
        print(f"cufund ros2: {e}", file=sys.stderr)
        return 2
    from cufund.scenarios.run_folder import run_into_folder

    p = cfg.ros2.params
    print(
        f"cufund ros2: domain {p.domain_id}, {'exposed' if p.expose else 'loopback only'}, "
        f"lockstep {'on ' + ', '.join(p.lockstep_nodes) if p.lockstep and p.lockstep_nodes else 'off'}",
        file=sys.stderr,
        flush=True,
    )
    try:
        run_ = run_into_folder(built, out, log=not args.no_log, replay=False, progress=False)
    except Ros2Timeout as e:
        print(f"cufund ros2: {e}", file=sys.stderr)
        return 1
    status = run_.result.status.value
    print(f"status: {status} ({run_.result.message})\nrun folder: {out.resolve()}")
    return 0 if status == "completed" else 1
