"""``cufund serve FLEET_SCENARIO``: a fleet scenario (one with ``vehicles:``) served as N PX4 SITL instances, one
MAVLink system per vehicle on PX4's multi-instance ports (:mod:`.fleet_ports`): ``--mavlink`` and ``--api`` name
vehicle 0's links, ``--system-id`` vehicle 0's system id. One line per vehicle is printed first,
``MAVLink vehicle <id> (<name>): <link> (local ...), ...``; Ctrl-C or SIGTERM stops."""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

__all__ = ["serve_fleet", "upload_mission"]


def upload_mission(live: Any, endpoints: Any, text: str, wait_s: float = 10.0) -> str:
    """Loads onto each vehicle the waypoints of the mission ``text`` asks for
    (:func:`cufund.missions.parse_mission`), as a MAVLink plan uploaded by a client would be: its commander's mission
    and its endpoint's plan (so QGroundControl and MAVSDK download it, and MISSION_CURRENT counts it). Returns ""
    when every vehicle took it, else why not (the request refused, with the reason, or a vehicle's refusal). Call
    before ``endpoints.start()``; the vehicles are not started: their clients start the mission."""

    import numpy as np
    from pymavlink.dialects.v20 import common as mavlink

    from cufund.missions import MissionRequestError, parse_mission

    from . import frames
    from .mission_protocol import MissionItem

    try:
        mission = parse_mission(text, live.fleet)
        waypoints = mission.waypoints(live.fleet)
    except (MissionRequestError, ValueError, TypeError) as e:
        return f"refused: {e}"
    for name, wp in waypoints.items():
        ep, run = endpoints.endpoint(name), live.vehicles[name]
        end = time.monotonic() + wait_s
        while run.telemetry().get("p_W") is None and time.monotonic() < end:  # its first state
            time.sleep(0.01)
        tel = run.telemetry()
        home = np.array(tel.get("home_p_W") or tel.get("p_W") or (0.0, 0.0, 0.0), dtype=float)
        home_amsl = float(ep.origin.enu_to_lla(home)[2])
        items = []
        for seq, p in enumerate(np.asarray(wp, dtype=float)):
            lat, lon, amsl = (float(c) for c in ep.origin.enu_to_lla(p))
            items.append(
                MissionItem(
                    seq,
                    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                    mavlink.MAV_CMD_NAV_WAYPOINT,
                    1,
                    0.0,
                    0.0,
                    0.0,
                    float("nan"),
                    int(frames.deg_to_e7(lat)),
                    int(frames.deg_to_e7(lon)),
                    amsl - home_amsl,
                )  # fmt: skip
            )
        result = ep.plan.accept(items)
        if result != mavlink.MAV_MISSION_ACCEPTED:
            return f"{name}: its commander refused the plan (MAV_MISSION_RESULT {result}): {run.telemetry().get('message')}"
        ep.missions.items = items
        print(f"{name}: mission of {len(items)} waypoints uploaded ({getattr(mission, 'kind', 'mission')})", flush=True)
    return ""


def serve_fleet(args: argparse.Namespace, config: Any, speed: float) -> int:
    """Serves ``config`` (a fleet) as ``cufund serve`` does a single vehicle; the exit code."""
    from .fleet_endpoints import FleetEndpoints
    from .fleet_live import LiveFleet
    from .fleet_ports import FleetPorts
    from .serve_wait import set_link_loss_timeout, wait_until_stopped, warn_exposed

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
    try:
        if args.link_loss_timeout is not None:
            refused = set_link_loss_timeout(live.vehicles, args.link_loss_timeout)
            if refused:
                print(f"cufund serve: {refused}", file=sys.stderr)
                return 2
        endpoints = FleetEndpoints(live.vehicles, ports, heartbeat_timeout_s=args.heartbeat_timeout)
        if getattr(args, "mission", None) is not None:
            refused = upload_mission(live, endpoints, args.mission)
            if refused:
                print(f"cufund serve: --mission: {refused}", file=sys.stderr)
                return 2
        endpoints.start()
        for line in endpoints.describe():
            print(line, flush=True)
        print(f"fleet of {len(live.names)}: scenario {args.scenario}, speed {speed:g}", flush=True)
        warn_exposed(lk for ep in endpoints.endpoints.values() for lk in ep.links)
        wait_until_stopped(args.duration)
        return 0
    except Exception as exc:  # e.g. an address in use
        print(f"cufund serve: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    finally:
        if endpoints is not None:
            endpoints.close()
        live.stop()
