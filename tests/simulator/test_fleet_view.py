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


def _scattered_world() -> World:
    world = World("scattered")
    world.add_plane((60.0, 60.0), (0.0, 0.0, 0.0))
    rng = np.random.default_rng(4)
    for _ in range(40):
        size = tuple(rng.uniform(0.3, 2.0, size=3))
        # clear of the floor: coplanar faces would make ties, which either structure may break either way
        lift = size[2] / 2 + 0.05
        world.add_box(size, position=tuple(rng.uniform(-20, 20, size=2)) + (lift,), yaw=float(rng.uniform(-3, 3)))
    return world


def test_a_view_shares_the_worlds_scene_and_casts_as_the_copied_meshes():
    """A view's scene instances the world's (not copied), and every ray reports what the flattened world with the
    boxes as its last object reports: distance, object id, triangle, barycentrics and normal, bit for bit."""
    from cufund import _core
    from cufund.simulator.fleet_view import VehicleBox, WorldWithVehicles, box_mesh_W

    base = _scattered_world()
    box = VehicleBox("b", BOX)
    poses = [((2.0, 1.0, 1.0), (1.0, 0.0, 0.0, 0.0)), ((-5.0, 3.0, 0.6), (0.9, 0.1, -0.2, 0.3))]
    vertices = np.concatenate([box_mesh_W(box, np.array(p), np.array(q) / np.linalg.norm(q)) for p, q in poses])
    triangles = np.concatenate([box.triangles, box.triangles + 8])
    view = WorldWithVehicles(base, vertices, triangles)
    assert base._scene is None
    assert view.raycast_scene is not None  # made from the base's scene (built now, once), not copies of its meshes
    assert base._scene is not None
    flat = World("flat")
    for obj in base.objects:
        flat.add_mesh(obj.vertices, obj.triangles, label=obj.label)
    flat.add_mesh(vertices, triangles, label="vehicles")
    rng = np.random.default_rng(5)
    n = 50000
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    rays = np.hstack([rng.uniform([-20, -20, 0.2], [20, 20, 3], size=(n, 3)), d]).astype(np.float32)
    vehicles_id = len(base.objects)
    for coherent in (None, True, False):
        a = view.raycast_scene.cast_rays(rays, nthreads=1, coherent=coherent)
        b = flat.raycast_scene.cast_rays(rays, nthreads=1, coherent=coherent)
        for key in b:
            assert np.array_equal(a[key], b[key]), (coherent, key)
    assert np.count_nonzero(b["geometry_ids"] == vehicles_id) > 0  # the boxes are hit, under their own id
    assert np.count_nonzero(b["geometry_ids"] < vehicles_id) > n // 4
    scene = base._scene
    for _ in range(3):  # more views of the same world share its one scene
        assert WorldWithVehicles(base, vertices, triangles).raycast_scene is not scene
    assert base._scene is scene
    # the shared scene cannot change under its views (Embree must not rebuild a scene another one traverses)
    n_base = scene.num_geometries
    with pytest.raises(ValueError, match="triangles cannot be added: another RaycastScene instances this one"):
        scene.add_triangles(vertices.astype(np.float32), triangles)
    assert scene.num_geometries == n_base
    # an empty base: the view is its boxes alone
    alone = WorldWithVehicles(World("none"), vertices, triangles).raycast_scene.cast_rays(rays[:2000], nthreads=1)
    assert set(np.unique(alone["geometry_ids"]).tolist()) <= {0, _core.lidar.RaycastScene.INVALID_ID}
