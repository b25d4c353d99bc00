"""A vehicle's LiDAR in a fleet sees the other vehicles: the forward beam of a 2-D scanner hits the other's box
where plain geometry puts its near face, and misses when the other is out of range."""

from __future__ import annotations

import numpy as np
import pytest

from cufund.core.messages import PointCloud
from cufund.core.topics import Topic
from cufund.sensors.lidar import Lidar, LidarParams
from cufund.sensors.lidar_component import LidarComponent
from cufund.sensors.patterns import PlanarPattern
from cufund.simulator import Simulator
from cufund.simulator.fleet import FleetMember, FleetSimulator
from cufund.vehicle import presets
from cufund.vehicle.quadrotor import Quadrotor
from cufund.worlds.world import World

BOX = (0.216, 0.216, 0.095)


def _forward_range(other_x: float, view_range_m: float | None = None) -> float:
    world = World("empty")
    world.add_plane((200.0, 200.0), (0.0, 0.0, 0.0))
    members = []
    comps = []
    for name, x in (("a", 0.0), ("b", other_x)):
        quad = Quadrotor(presets.cu_astro())
        quad.hover(np.array([x, 0.0, 1.0]))
        sim = Simulator(quad, record_topics=[Topic("/sensors/scan", PointCloud)])
        lidar = Lidar(PlanarPattern(), LidarParams(range_min=0.05, range_max=30.0, range_noise_std=0.0))
        comp = LidarComponent(lidar, world, "/sensors/scan", rate_hz=40.0, truth_topic="/truth/scan")
        sim.add(comp)
        comps.append(comp)
        members.append(FleetMember(name, sim, box_size=BOX, viewers=[comp], world=world, view_range_m=view_range_m))
    fleet = FleetSimulator(members, world)
    fleet.reset()
    fleet.advance_to(0.1)
    scans = members[0].simulator.result().topics["/sensors/scan"]
    pts, ranges = scans["points_L"][-1], scans["ranges"][-1]
    fwd = np.abs(np.arctan2(pts[:, 1], pts[:, 0])) < np.deg2rad(0.2)
    return float(ranges[fwd].min()) if np.any(fwd) else float("inf")


def test_lidar_sees_the_other_vehicle():
    # the other's box: its near face at other_x - 0.108 m, the scanner at the body origin
    assert _forward_range(2.0) == pytest.approx(2.0 - BOX[0] / 2, abs=1e-3)


def test_nothing_there_when_out_of_view_range():
    assert _forward_range(60.0) == float("inf")  # beyond the LiDAR's 30 m
    # within the LiDAR's reach but beyond the vehicle's view range: left out of its view
    assert _forward_range(15.0, view_range_m=20.0) == pytest.approx(15.0 - BOX[0] / 2, abs=1e-3)
    assert _forward_range(25.0, view_range_m=20.0) == float("inf")


def test_a_fleet_sees_as_far_as_each_vehicles_sensors():
    from cufund.scenarios.fleet import IMAGE_CAMERA_RANGE_M, sensing_range
    from cufund.sensors.camera import DepthCamera, RgbCamera

    lidar = LidarComponent(Lidar(PlanarPattern(), LidarParams(range_max=12.0)), World(), "/sensors/scan", rate_hz=40.0)
    assert sensing_range(lidar) == 12.0
    assert sensing_range(type("C", (), {"camera": DepthCamera(depth_max=7.0)})()) == 7.0
    assert sensing_range(type("C", (), {"camera": RgbCamera()})()) == IMAGE_CAMERA_RANGE_M
