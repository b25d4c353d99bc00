"""A run ends CRASHED, with the contact, when the vehicle's shape touches a world object (Bullet)."""

import numpy as np
import pytest

import cufund
from cufund.simulator import RunStatus, Simulator
from cufund.worlds import CollisionChecker


def _world(wall_y: float) -> cufund.World:
    w = cufund.World("test")
    w.add_plane((20.0, 20.0), (0.0, 0.0, 0.0), label="floor")
    w.add_box((0.2, 2.0, 3.0), (2.0, wall_y, 1.5), label="wall")  # its near face at x = 1.9 m
    return w


def _coast(world: cufund.World, rate_hz: float = 1000.0):
    params = cufund.vehicle.presets.cu_astro()
    quad = cufund.Quadrotor(params)
    quad.hover((0.0, 0.0, 1.0))
    quad.state.v[:] = (2.0, 0.0, 0.0)  # hover thrust, coasting towards +x (drag slows it a little)
    checker = CollisionChecker(world, box_size=(0.216, 0.216, 0.095), ignore_labels=("floor",))
    return Simulator(quad, collision=checker, collision_rate_hz=rate_hz).run(2.0)


def test_flying_into_a_wall_crashes_with_the_contact():
    result = _coast(_world(0.0))
    assert result.status is RunStatus.CRASHED
    c = result.contact
    assert c is not None and c.label == "wall" and c.object_id == 1
    assert c.point_W[0] == pytest.approx(1.9, abs=1e-3)  # on the wall's near face
    assert c.distance < 0.0
    # The box's front (half of 0.216 m) reaches x = 1.9 at t ~ (1.9 - 0.108) / ~2 m/s.
    x_front = result.states["p_W"][-1, 0] + 0.108
    assert x_front == pytest.approx(1.9, abs=0.01)
    assert "wall" in result.message and result.sim_time_s < 1.0


def test_a_near_miss_and_the_floor_do_not_crash():
    result = _coast(_world(1.15))  # wall from y = 0.15 to 2.15: passes 4 cm beside the 0.108 m half-width
    assert result.status is RunStatus.COMPLETED and result.contact is None


def test_collision_rate_must_divide_physics_rate():
    quad = cufund.Quadrotor(cufund.vehicle.presets.cu_astro())
    with pytest.raises(ValueError, match="collision_rate_hz must divide the physics rate"):
        Simulator(quad, collision=CollisionChecker(_world(0.0), radius=0.1), collision_rate_hz=300.0)
    with pytest.raises(TypeError, match="collision must be a cufund.worlds.CollisionChecker"):
        Simulator(quad, collision="wall")  # type: ignore[arg-type]


def test_ignored_labels_keep_world_object_ids():
    checker = CollisionChecker(_world(0.0), radius=0.1, ignore_labels=("floor",))
    assert checker.check(np.array([0.0, 0.0, 0.05]), np.array([1.0, 0, 0, 0])) is None  # floor ignored
    hit = checker.check(np.array([1.95, 0.0, 1.0]), np.array([1.0, 0, 0, 0]))
    assert hit is not None and hit.object_id == 1 and hit.label == "wall"
