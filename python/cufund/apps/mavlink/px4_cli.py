"""``cufund px4-sim SCENARIO``: serve a scenario to PX4 as its simulator — SITL over TCP 4560 + instance (lockstep)
or HITL over a serial port (``--hitl DEVICE``, lockstep off). Exit codes: 0 the session ended (PX4 left in order or
the duration elapsed), 1 the vehicle crashed or diverged, or the link failed (e.g. PX4 reset the connection; the
reason on stderr), 2 invalid configuration or usage."""

from __future__ import annotations

import argparse
import math
import os
import sys

from cufund.core.config import ConfigError

from ..arguments import add_overrides

EXIT_OK, EXIT_NOT_COMPLETED, EXIT_INVALID = 0, 1, 2


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", help="a built-in scenario name or a YAML file (its flight software is replaced by PX4)")
    p.add_argument("--instance", type=int, default=0, help="PX4 instance: listen on TCP 4560 + N (default 0)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    p.add_argument(
        "--hitl",
        metavar="DEVICE",
        help="HITL: talk to a flight controller on this serial port (e.g. /dev/ttyACM0) instead of px4_sitl over TCP",
    )
    p.add_argument("--baud", type=int, default=921600, help="HITL serial baud rate (default 921600)")
    p.add_argument(
        "--gcs",
        default="127.0.0.1:14550",
        metavar="HOST:PORT",
        help="HITL: relay the flight controller's MAVLink to a ground station over UDP and back "
        "(default 127.0.0.1:14550, QGroundControl's port; 'none' to disable)",
    )
    add_overrides(p, help="override a scenario field by its dotted key, e.g. --set vehicle=iris (repeatable)")
    p.add_argument(
        "--speed",
        default="1",
        metavar="FACTOR",
        help="simulated seconds per wall second (PX4_SIM_SPEED_FACTOR's role; default 1), or 'max'",
    )
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        help="stop after this much simulated time [s] (default: until PX4 disconnects)",
    )
    p.add_argument(
        "--connect-timeout",
        type=float,
        default=None,
        help="give up if PX4 has not connected after this many seconds (default: wait forever)",
    )
    p.add_argument(
        "--cpu",
        type=int,
        default=None,
        metavar="N",
        help="run on CPU N only (Linux); lockstep is serial, so with PX4 on the same CPU (taskset -c N) "
        "neither side waits for the other to be woken on another CPU",
    )


def _speed(text: str) -> float | None:
    if text.strip().lower() in ("max", "inf", "none"):
        return None
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value <= 0:
        raise ConfigError(f"--speed must be a real-time factor > 0 or 'max', got {text!r}")
    return value


def _gcs(text: str) -> tuple[str, int] | None:
    if text.strip().lower() == "none":
        return None
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ConfigError(f"--gcs must be HOST:PORT (e.g. 127.0.0.1:14550) or 'none', got {text!r}")
    return host, int(port)


def run(args: argparse.Namespace) -> int:
    from cufund.scenarios.schema import load_scenario, parse_overrides

    from .px4_links import GcsForward, SerialLink, TcpServerLink
    from .px4_sim import Px4BridgeParams, Px4SimulatorBridge

    link = gcs = None
    try:
        speed = _speed(args.speed)
        if args.hitl and speed is None:
            raise ConfigError(
                "--speed max needs lockstep; HITL runs against the flight controller's clock, give a "
                "factor (1 is real time)"
            )
        if args.duration is not None and not (math.isfinite(args.duration) and args.duration > 0):
            raise ConfigError(f"--duration must be a number of seconds > 0, got {args.duration!r}")
        if not 0 <= args.instance <= 60000:
            raise ConfigError(f"--instance must be in [0, 60000], got {args.instance}")
        if args.cpu is not None:
            cpus = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else []
            if args.cpu not in cpus:
                raise ConfigError(f"--cpu must be one of the CPUs this process may use {cpus}, got {args.cpu}")
        config = load_scenario(args.scenario, parse_overrides(args.overrides))
        params = Px4BridgeParams(speed=speed, lockstep=args.hitl is None)
        if config.vehicles is not None:  # a fleet: N SITL instances on TCP 4560 + instance + i (fleet_px4.py)
            from .fleet_px4 import serve_px4_fleet

            return serve_px4_fleet(args, config, params)
        gcs_address = _gcs(args.gcs) if args.hitl else None
        link = SerialLink(args.hitl, args.baud) if args.hitl else TcpServerLink(args.host, 4560 + args.instance)
        gcs = GcsForward(*gcs_address) if gcs_address is not None else None
        bridge = Px4SimulatorBridge(config, link, params, gcs=gcs)
    except (ConfigError, ValueError, OSError) as e:
        for opened in (link, gcs):
            if opened is not None:
                opened.close()
        print(f"cufund: {e}", file=sys.stderr)
        return EXIT_INVALID
    if args.cpu is not None:
        os.sched_setaffinity(0, {args.cpu})  # before any thread starts: they inherit it
    where = (
        f"serial {args.hitl} at {args.baud} baud (HITL, lockstep off"
        + (f"; ground station relay udp://{gcs.address[0]}:{gcs.address[1]})" if gcs else ")")
        if args.hitl
        else f"tcp://{args.host}:{bridge.port_number} (SITL, lockstep)"
    )
    vehicle = bridge.simulator.vehicle
    vehicle_name = vehicle.params.name if vehicle is not None else "no vehicle"
    print(
        f"cufund px4-sim: {config.name} on {vehicle_name}, waiting for PX4 on {where}",
        flush=True,
    )
    try:
        result = bridge.run(duration=args.duration, connect_timeout=args.connect_timeout)
    except TimeoutError as e:
        print(f"cufund: {e}", file=sys.stderr)
        return EXIT_NOT_COMPLETED
    except KeyboardInterrupt:
        print("cufund px4-sim: interrupted", file=sys.stderr)
        return EXIT_OK
    finally:
        bridge.close()
    s = bridge.stats
    print(
        f"status: {result.status.value} ({result.message}) after {result.sim_time_s:.3f} s simulated; "
        f"HIL_SENSOR {s['hil_sensor']}, HIL_GPS {s['hil_gps']}, HIL_STATE_QUATERNION {s['hil_state_quaternion']}, "
        f"controls {s['controls']}, timeouts {s['controls_timeouts']}, bad packets {s['bad_packets']}"
    )
    if result.status.value == "aborted":
        print(f"cufund px4-sim: {result.message}", file=sys.stderr)
    return EXIT_OK if result.status.value == "completed" else EXIT_NOT_COMPLETED
