"""The MAVLink and simulator ports of a fleet's vehicles: PX4 SITL's multi-instance rule, so that QGroundControl,
MAVSDK and MAVProxy find N vehicles where they find N ``px4_sitl -i`` instances.

Vehicle ``i`` (0-based, in the order of the scenario's ``vehicles:``) is MAVLink system ``i + 1`` and has:

========================  =========================================  ==========================================
link                      sends to (remote)                          from (local port)
========================  =========================================  ==========================================
ground station            ``14550`` (every vehicle: QGC tells them   ``18570 + i``
                          apart by system id)
offboard API (MAVSDK)     ``14540 + i``                              ``14580 + i``
PX4 simulator (px4-sim)   --                                         TCP ``4560 + i`` (listens)
========================  =========================================  ==========================================

These are PX4's ``px4-rc.mavlink`` ports (``udp_gcs_port_local=18570+i``, ``udp_offboard_port_local=14580+i``,
``udp_offboard_port_remote=14540+i``) and its simulator port (``4560+i``). A ``udpin:HOST:PORT`` link instead
listens on ``PORT + i`` (two vehicles cannot share one listening port). Everything binds 127.0.0.1 unless a URL
names another address.
"""

from __future__ import annotations

from dataclasses import dataclass

from .link import LinkAddress, _is_loopback
from .px4_links import PX4_SITL_BASE_PORT

__all__ = [
    "API_LOCAL_BASE",
    "GCS_LOCAL_BASE",
    "MAX_VEHICLES",
    "PX4_SIM_BASE",
    "FleetPorts",
    "VehiclePorts",
    "px4_sim_port",
]

GCS_LOCAL_BASE = 18570
"""PX4 instance i's ground-station link sends from local port 18570 + i."""
API_LOCAL_BASE = 14580
"""PX4 instance i's offboard link sends from local port 14580 + i (to 14540 + i)."""
PX4_SIM_BASE = PX4_SITL_BASE_PORT
"""PX4 instance i connects to its simulator on TCP 4560 + i."""
MAX_VEHICLES = 255
"""MAVLink system ids are 1..255."""


@dataclass(frozen=True)
class VehiclePorts:
    """One vehicle's MAVLink identity and links."""

    index: int
    system_id: int
    links: tuple[tuple[str, int], ...]
    """(URL, local port) per link; local port 0: any free port (a ``udpin`` link's port is in its URL)."""


@dataclass(frozen=True)
class FleetPorts:
    """The port rule of a fleet (module docstring). ``gcs`` and ``api`` are vehicle 0's link URLs (None: leave the
    link out); ``px4_local_ports=False`` lets the kernel pick the local ports of ``udpout`` links (tests running
    next to a real PX4, or two fleets on one machine)."""

    gcs: str | None = "udpout:127.0.0.1:14550"
    api: str | None = "udpout:127.0.0.1:14540"
    px4_local_ports: bool = True
    first_system_id: int = 1
    """Vehicle i is MAVLink system ``first_system_id + i`` (PX4: ``MAV_SYS_ID = instance + 1``)."""

    def __post_init__(self) -> None:
        f = self.first_system_id
        if isinstance(f, bool) or not isinstance(f, int) or not 1 <= f <= MAX_VEHICLES:
            raise ValueError(f"FleetPorts.first_system_id must be an integer in [1, {MAX_VEHICLES}], got {f!r}")
        if self.gcs is None and self.api is None:
            raise ValueError("FleetPorts: give at least one of gcs and api (both are None)")
        for name in ("gcs", "api"):
            url = getattr(self, name)
            if url is not None:
                LinkAddress.parse(url, name)

    def vehicle(self, index: int, count: int) -> VehiclePorts:
        """The ports of vehicle ``index`` of ``count`` (ValueError naming what is wrong)."""
        most = MAX_VEHICLES - self.first_system_id + 1
        if isinstance(count, bool) or not isinstance(count, int) or not 1 <= count <= most:
            raise ValueError(
                f"a fleet has 1 to {most} vehicles here (one MAVLink system id each, from {self.first_system_id} "
                f"to 255), got {count!r}"
            )
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < count:
            raise ValueError(f"vehicle index must be in [0, {count - 1}], got {index!r}")
        links = []
        for url, shared_remote, local_base in ((self.gcs, True, GCS_LOCAL_BASE), (self.api, False, API_LOCAL_BASE)):
            if url is None:
                continue
            a = LinkAddress.parse(url)
            if a.mode == "udpin":
                port = a.port + index if a.port else 0
                _check_port(port, url, count)
                links.append((f"udpin:{a.host}:{port}", 0))
                continue
            remote = a.port if shared_remote else a.port + index
            _check_port(remote, url, count)
            local = local_base + index if self.px4_local_ports else 0
            links.append((f"udpout:{a.host}:{remote}", local))
        return VehiclePorts(index, self.first_system_id + index, tuple(links))

    def all(self, count: int) -> list[VehiclePorts]:
        """Every vehicle's ports; ValueError when two vehicles would share a port."""
        out = [self.vehicle(i, count) for i in range(count)]
        local = [lp for v in out for _, lp in v.links if lp]
        listen = [int(url.rsplit(":", 1)[1]) for v in out for url, _ in v.links if url.startswith("udpin:")]
        taken = [p for p in listen if p] + local
        if len(taken) != len(set(taken)):
            raise ValueError(
                f"the links of {count} vehicles overlap (ground station {self.gcs!r}, API {self.api!r}): give "
                "base ports at least the fleet's size apart"
            )
        # a link sending on this machine to a port one of the fleet's own sockets holds would be that vehicle's
        # client (PX4's rule at 41 vehicles: the offboard link to 14540 + 40 = 14580, vehicle 0's local port)
        remote = [
            (v.index, a.port)
            for v in out
            for url, _ in v.links
            if (a := LinkAddress.parse(url)).mode == "udpout" and _is_loopback(a.host)
        ]
        clash = [(i, port) for i, port in remote if port in taken]
        if clash:
            i, port = clash[0]
            raise ValueError(
                f"vehicle {i + 1} of {count} would send to 127.0.0.1:{port}, a port the fleet's own links hold: "
                "use --local-ports any (FleetPorts(px4_local_ports=False)) or base ports further apart"
            )
        return out


def _check_port(port: int, url: str, count: int) -> None:
    if not 0 <= port <= 65535:
        raise ValueError(f"{url!r}: port + vehicle index is out of range for {count} vehicles (got {port})")


def px4_sim_port(instance: int) -> int:
    """TCP port PX4 instance ``instance`` connects to its simulator on (4560 + instance)."""
    return PX4_SIM_BASE + instance
