"""``cufund gcs [SCENARIO]``: a live run of SCENARIO and the web ground station serving it on 127.0.0.1.

The first line of output is ``GCS: http://127.0.0.1:PORT/?token=TOKEN``; open it in a browser. With
``--foxglove`` the second is ``Foxglove: ws://127.0.0.1:PORT/?token=TOKEN`` (the same token) for Foxglove.
Ctrl-C stops.

The port is :data:`DEFAULT_PORT` on every launch (a bookmark keeps working) unless it is taken: then a free one,
said on stderr; ``--port N`` insists on N (exit 2 when taken), ``--port 0`` takes any free port. The run waits for
the operator's Start (``--autostart``: at once, for scripts).
"""

from __future__ import annotations

import argparse
import asyncio
import signal
import sys

from ..arguments import add_overrides
from .guard import LOOPBACK
from .server import GcsServer, parse_speed

__all__ = ["add_arguments", "run"]

DEFAULT_SCENARIO = "vehicle"
DEFAULT_PORT = 8780
"""The ground station's port unless ``--port`` is given (a free one when it is taken)."""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "scenario",
        nargs="?",
        default=DEFAULT_SCENARIO,
        help=f"scenario name or YAML path (default: {DEFAULT_SCENARIO})",
    )
    p.add_argument(
        "--host",
        default="127.0.0.1",
        help="interface to serve on (default 127.0.0.1; anything else exposes the vehicle's commands)",
    )
    p.add_argument(
        "--port",
        type=int,
        default=None,
        help=f"port (default {DEFAULT_PORT}, or a free one when that is taken; 0: any free port)",
    )
    p.add_argument(
        "--autostart",
        action="store_true",
        help="start the scenario's mission (or its run) at once instead of waiting for the page's Start (scripts)",
    )
    p.add_argument("--speed", default="1", help="simulation speed: 0.1 to 10 times real time, or inf (default 1)")
    add_overrides(p)
    p.add_argument(
        "--foxglove",
        action="store_true",
        help="also serve the topics over a Foxglove WebSocket server (needs the same token)",
    )
    p.add_argument("--foxglove-port", type=int, default=8765, help="the Foxglove server's port (default 8765)")
    p.add_argument("--telemetry-hz", type=float, default=50.0, help="telemetry rate to the page (default 50)")


def run(args: argparse.Namespace) -> int:
    try:
        speed = parse_speed(args.speed)
    except ValueError as exc:
        print(f"cufund gcs: {exc}", file=sys.stderr)
        return 2
    if args.port is not None and not 0 <= args.port < 65536 or not 0 <= args.foxglove_port < 65536:
        print("cufund gcs: --port and --foxglove-port must be in [0, 65535]", file=sys.stderr)
        return 2
    if args.host not in LOOPBACK:
        print(
            f"cufund gcs: WARNING: serving on {args.host}: anyone who can reach it and has the token can command "
            "the vehicle",
            file=sys.stderr,
        )
    return asyncio.run(_serve(args, speed))


async def _serve(args: argparse.Namespace, speed: float) -> int:
    foxglove = None
    if args.foxglove:
        from .foxglove_bridge import FoxgloveBridge

        foxglove = FoxgloveBridge(port=args.foxglove_port)
    try:
        from .fleet_server import fleet_server_for  # a fleet scenario (vehicles:): the fleet's station

        port = DEFAULT_PORT if args.port is None else args.port
        fleet = fleet_server_for(
            args.scenario, tuple(args.overrides), speed, args.host, port, args.port is None, args.autostart
        )
        server = fleet or GcsServer(
            args.scenario,
            tuple(args.overrides),
            speed,
            host=args.host,
            port=DEFAULT_PORT if args.port is None else args.port,
            telemetry_hz=args.telemetry_hz,
            foxglove=foxglove,
            autostart=args.autostart,
            port_fallback=args.port is None,
        )
        url = server.start()
    except Exception as exc:  # a bad scenario or a busy port: say so, exit 2
        print(f"cufund gcs: {type(exc).__name__}: {exc}", file=sys.stderr)
        if foxglove is not None:
            foxglove.stop()
        return 2
    if server.port_note:  # before the URL line: a script that reads that line may stop the server at once
        print(f"cufund gcs: {server.port_note}", file=sys.stderr, flush=True)
    print(f"GCS: {url}", flush=True)
    if foxglove is not None:
        print(f"Foxglove: {foxglove.url}", flush=True)
    done = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, done.set)
    await done.wait()
    server.stop()
    if foxglove is not None:
        foxglove.stop()
    return 0
