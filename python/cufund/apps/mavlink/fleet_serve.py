"""``cufund serve FLEET_SCENARIO``: a fleet scenario (one with ``vehicles:``) served as N PX4 SITL instances, one
MAVLink system per vehicle on PX4's multi-instance ports (:mod:`.fleet_ports`): ``--mavlink`` and ``--api`` name
vehicle 0's links, ``--system-id`` vehicle 0's system id. One line per vehicle is printed first,
``MAVLink vehicle <id> (<name>): <link> (local ...), ...``; Ctrl-C or SIGTERM stops."""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
import time
from typing import Any

__all__ = ["fleet_config", "serve_fleet"]


def fleet_config(scenario: str, overrides: Any) -> Any:
    """The scenario's config when it is a fleet (it has ``vehicles:``), else None. Errors as ``load_scenario``."""
    from cufund.scenarios.schema import load_scenario

    config = load_scenario(scenario, overrides)
    return config if getattr(config, "vehicles", None) is not None else None


def serve_fleet(args: argparse.Namespace, config: Any, speed: float) -> int:
    """Serves ``config`` (a fleet) as ``cufund serve`` does a single vehicle; the exit code."""
    from .fleet_endpoints import FleetEndpoints
    from .fleet_live import LiveFleet
    from .fleet_ports import FleetPorts

    def none(url: str | None) -> str | None:
        return None if url is None or url.lower() == "none" else url

    try:
        ports = FleetPorts(
            gcs=none(args.mavlink),
            api=none(args.api),
            px4_local_ports=getattr(args, "local_ports", "px4") == "px4",
            first_system_id=args.system_id,
        )
        ports.all(len(config.vehicles))
    except ValueError as exc:
        print(f"cufund serve: {exc}", file=sys.stderr)
        return 2
    try:
        live = LiveFleet(config, speed=speed)
    except Exception as exc:  # an invalid fleet: exit 2, no traceback
        print(f"cufund serve: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    endpoints = None
    previous: dict[signal.Signals, Any] = {}
    try:
        if args.link_loss_timeout is not None:
            cmd = {"command": "set_param", "name": "COM_DL_LOSS_T", "value": float(args.link_loss_timeout)}
            for name, fut in live.submit_all(cmd).items():
                ack = fut.result(timeout=10.0)
                if ack.result != "accepted":
                    print(f"cufund serve: --link-loss-timeout ({name}): {ack.message}", file=sys.stderr)
                    return 2
        endpoints = FleetEndpoints(live.vehicles, ports, heartbeat_timeout_s=args.heartbeat_timeout)
        endpoints.start()
        for line in endpoints.describe():
            print(line, flush=True)
        print(f"fleet of {len(live.names)}: scenario {args.scenario}, speed {speed:g}", flush=True)
        for ep in endpoints.endpoints.values():
            for lk in ep.links:
                host = lk.local_address[0]
                if not host.startswith("127."):
                    print(
                        f"cufund serve: warning: {lk.address.mode}:{lk.address.host}:{lk.address.port} listens on "
                        f"{host or '0.0.0.0'}: other machines can command this vehicle",
                        file=sys.stderr,
                        flush=True,
                    )
        stop = threading.Event()
        if threading.current_thread() is threading.main_thread():  # (restored on the way out)
            for sig in (signal.SIGINT, signal.SIGTERM):
                previous[sig] = signal.signal(sig, lambda *_: stop.set())
        deadline = math.inf if args.duration is None else time.monotonic() + args.duration
        while not stop.is_set() and time.monotonic() < deadline:
            stop.wait(0.2)
        return 0
    except Exception as exc:  # e.g. an address in use
        print(f"cufund serve: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if endpoints is not None:
            endpoints.close()
        live.stop()
