"""A fleet on MAVLink: one :class:`VehicleEndpoint` per vehicle, vehicle ``i`` being system ``i + 1`` on its own
links by PX4 SITL's multi-instance port rule (:mod:`.fleet_ports`), so ground stations and MAVSDK see N vehicles.

Each vehicle's run is anything a :class:`VehicleEndpoint` serves: a :class:`cufund.apps.live.LiveRun`, or one
vehicle's view of a live fleet (:class:`cufund.apps.mavlink.fleet_live.LiveFleet`). Each endpoint keeps its own
thread, stream rates, mission, parameters and link-loss watch: what one client does to one vehicle never reaches
another.
"""

from __future__ import annotations

import socket
from collections.abc import Mapping
from typing import Any

from .fleet_ports import FleetPorts
from .link import UdpLink
from .vehicle_endpoint import VehicleEndpoint

__all__ = ["FleetEndpoints"]


def _bind_local(link: UdpLink, port: int) -> None:
    """Moves ``link``'s socket (a fresh ``udpout`` one, not yet used) to local ``port`` on the same address, as a
    PX4 instance's link sends from its fixed local port. OSError (e.g. the port is taken) names the port."""
    host = link.local_address[0]
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        sock.bind((host, port))
    except OSError as e:
        sock.close()
        raise OSError(e.errno, f"{link.name}: cannot bind local port {host or '0.0.0.0'}:{port}: {e.strerror}") from e
    sock.setblocking(False)
    old, link.sock = link.sock, sock
    old.close()


class FleetEndpoints:
    """Serves ``runs`` (vehicle name -> run, in fleet order) on MAVLink by ``ports``' rule. ``endpoint_kw`` goes to
    every :class:`VehicleEndpoint` (e.g. ``heartbeat_timeout_s``). Sockets are bound at construction (OSError if a
    port is taken, nothing left open); :meth:`start` starts serving, :meth:`close` stops every endpoint."""

    def __init__(self, runs: Mapping[str, Any], ports: FleetPorts | None = None, **endpoint_kw: Any) -> None:
        if not isinstance(runs, Mapping) or not runs:
            raise ValueError("runs must map each vehicle's name to its run, with at least one vehicle")
        self.ports = ports or FleetPorts()
        plan = self.ports.all(len(runs))
        self.names: tuple[str, ...] = tuple(runs)
        self.endpoints: dict[str, VehicleEndpoint] = {}
        try:
            for name, vp in zip(self.names, plan, strict=True):
                ep = VehicleEndpoint(runs[name], [url for url, _ in vp.links], system_id=vp.system_id, **endpoint_kw)
                self.endpoints[name] = ep
                for link, (_, local) in zip(ep.links, vp.links, strict=True):
                    if local:
                        _bind_local(link, local)
        except Exception:
            self.close()
            raise

    def system_id(self, name: str) -> int:
        return self.endpoint(name).system_id

    def endpoint(self, name: str) -> VehicleEndpoint:
        try:
            return self.endpoints[name]
        except KeyError:
            raise KeyError(f"no vehicle {name!r} in this fleet; it has {list(self.names)}") from None

    def start(self) -> FleetEndpoints:
        for ep in self.endpoints.values():
            ep.start()
        return self

    def close(self) -> None:
        for ep in self.endpoints.values():
            ep.close()

    def __enter__(self) -> FleetEndpoints:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def describe(self) -> list[str]:
        """One line per vehicle: ``MAVLink vehicle <sysid> (<name>): <mode>:<host>:<port> (local <host>:<port>), ...``."""
        lines = []
        for name, ep in self.endpoints.items():
            links = ", ".join(
                f"{lk.address.mode}:{lk.address.host}:{lk.address.port} "
                f"(local {lk.local_address[0]}:{lk.local_address[1]})"
                for lk in ep.links
            )
            lines.append(f"MAVLink vehicle {ep.system_id} ({name}): {links}")
        return lines
