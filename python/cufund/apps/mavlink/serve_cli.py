"""``cufund serve [SCENARIO]``: a live run of SCENARIO as a PX4 vehicle on MAVLink.

Ground stations listen on 14550 (``--mavlink udpout:127.0.0.1:14550``), offboard programs such as MAVSDK on 14540
(``--api udpout:127.0.0.1:14540``); ``udpin:HOST:PORT`` listens instead. Sockets bind 127.0.0.1 unless an URL
names another address. The first line printed is ``MAVLink vehicle <id>: <link> ...``; Ctrl-C or SIGTERM stops.
A fleet scenario (``vehicles:``) is served as N PX4 SITL instances, one system each (:mod:`.fleet_serve`).
"""

from __future__ import annotations

import argparse
import math
import sys

from ..arguments import add_overrides
from .serve_wait import set_link_loss_timeout, wait_until_stopped, warn_exposed

__all__ = ["add_arguments", "run"]

DEFAULT_SCENARIO = "vehicle"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "scenario",
        nargs="?",
        default=DEFAULT_SCENARIO,
        help=f"scenario name or YAML path (default: {DEFAULT_SCENARIO}, the commander's vehicle)",
    )
    p.add_argument(
        "--mavlink",
        default="udpout:127.0.0.1:14550",
        help="ground-station link (default udpout:127.0.0.1:14550; 'none' to leave it out)",
    )
    p.add_argument(
        "--api",
        default="udpout:127.0.0.1:14540",
        help="offboard-API link, e.g. MAVSDK (default udpout:127.0.0.1:14540; 'none' to leave it out)",
    )
    p.add_argument("--speed", default="1", help="simulation speed: times real time (> 0, default 1)")
    add_overrides(p)
    p.add_argument(
        "--link-loss-timeout",
        type=float,
        default=None,
        metavar="S",
        help="after a link loss the vehicle holds, then lands after S seconds (COM_DL_LOSS_T)",
    )
    p.add_argument(
        "--heartbeat-timeout",
        type=float,
        default=3.0,
        metavar="S",
        help="no message from any client for S wall-clock seconds is a link loss (default 3)",
    )
    p.add_argument(
        "--system-id", type=int, default=1, help="MAVLink system id (default 1; a fleet's vehicle i: this + i)"
    )
    p.add_argument(
        "--mission",
        metavar="TEXT",
        default=None,
        help="a fleet: upload the mission this plain-language request asks for to its vehicles before serving "
        "(e.g. 'zigzag with 3 rows of 5 waypoints at 3 m'; clients start it); a refused request exits 2 with why",
    )
    p.add_argument(
        "--local-ports",
        choices=("px4", "any"),
        default="px4",
        help="a fleet's udpout links send from PX4 SITL's local ports (18570 + i, 14580 + i; default) or any free one",
    )
    p.add_argument(
        "--telemetry-hz",
        type=float,
        default=250.0,
        help="rate of the run's state snapshots the streams read [Hz of simulated time] (default 250: "
        "~4 ms median state-to-client latency)",
    )
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="stop after S wall-clock seconds (default: run until interrupted)",
    )


def run(args: argparse.Namespace) -> int:
    try:
        speed = float(args.speed)
        if not (speed > 0 and math.isfinite(speed)):
            raise ValueError
    except ValueError:
        print(f"cufund serve: --speed must be a number > 0, got {args.speed!r}", file=sys.stderr)
        return 2
    for option, value in (
        ("--link-loss-timeout", args.link_loss_timeout),
        ("--heartbeat-timeout", args.heartbeat_timeout),
        ("--telemetry-hz", args.telemetry_hz),
    ):
        if value is not None and not (math.isfinite(value) and value > 0):
            print(f"cufund serve: {option} must be a number > 0, got {value!r}", file=sys.stderr)
            return 2
    urls = [u for u in (args.mavlink, args.api) if u and u.lower() != "none"]
    if not urls:
        print("cufund serve: give at least one of --mavlink and --api", file=sys.stderr)
        return 2
    from cufund.scenarios.schema import load_scenario, parse_overrides

    from .link import LinkAddress

    try:
        for u in urls:
            LinkAddress.parse(u, "--mavlink/--api")
        overrides = parse_overrides(list(args.overrides))
    except Exception as exc:  # bad usage: say so, exit 2
        print(f"cufund serve: {exc}", file=sys.stderr)
        return 2
    try:
        config = load_scenario(args.scenario, overrides)
    except Exception as exc:  # an invalid scenario: exit 2, no traceback
        print(f"cufund serve: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    if config.vehicles is not None:  # N vehicles: N MAVLink systems on PX4 SITL's multi-instance ports
        from .fleet_serve import serve_fleet

        return serve_fleet(args, config, speed)
    if getattr(args, "mission", None) is not None:
        print("cufund serve: --mission is for a fleet scenario (vehicles:)", file=sys.stderr)
        return 2
    from ..live import LiveRun
    from .vehicle_endpoint import VehicleEndpoint

    try:
        live = LiveRun(config, speed=speed, telemetry_hz=args.telemetry_hz)
    except Exception as exc:  # an invalid scenario: exit 2, no traceback
        print(f"cufund serve: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    endpoint = None
    try:
        if args.link_loss_timeout is not None:
            refused = set_link_loss_timeout({"": live}, args.link_loss_timeout)
            if refused:
                print(f"cufund serve: {refused}", file=sys.stderr)
                return 2
        endpoint = VehicleEndpoint(live, urls, system_id=args.system_id, heartbeat_timeout_s=args.heartbeat_timeout)
        endpoint.start()
        links = ", ".join(
            f"{lk.address.mode}:{lk.address.host}:{lk.address.port} (local {lk.local_address[0]}:{lk.local_address[1]})"
            for lk in endpoint.links
        )
        print(f"MAVLink vehicle {args.system_id}: {links}; scenario {args.scenario}, speed {speed:g}", flush=True)
        warn_exposed(endpoint.links)
        wait_until_stopped(args.duration)
        return 0
    except Exception as exc:  # e.g. an address in use
        print(f"cufund serve: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    finally:
        if endpoint is not None:
            endpoint.close()
        live.stop()
