"""No flight software reads the truth (issue 31), for every built-in scenario that flies on an estimate.

Flight software is every component whose class does not live in ``cufund.sensors`` (the simulated sensor models);
for each built-in scenario, built and run for two simulated seconds:

(a) no flight component declares or reads a ``/truth/`` topic (the bus records every topic a component read);
(b) no flight part read the world while it was built (``ScenarioBuildContext.world_readers``: only the world
    itself and the simulated sensors may; harness-only uses go through ``truth_world_for_metrics()``);
(c) no flight component holds a truth object: walking its attributes (containers, dataclasses, closures) reaches
    no world, tunnel course, collision checker, plant, simulator, build context, sensor model or LiDAR truth.
"""

from __future__ import annotations

import dataclasses
import types
from typing import Any

import numpy as np
import pytest

from cufund import ScenarioConfig
from cufund.core.build_context import BuildContext
from cufund.core.bus import Bus, BusView, Subscription
from cufund.core.components import Component, Sensor
from cufund.core.messages import LidarTruth
from cufund.core.registry import Kind, register, unregister
from cufund.core.topics import is_truth
from cufund.missions.tunnel_course import TunnelCourse
from cufund.scenarios import load_scenario
from cufund.scenarios.build import ScenarioBuildContext, build_simulation
from cufund.scenarios.fleet import build_fleet
from cufund.simulator import Simulator
from cufund.vehicle.quadrotor import Quadrotor
from cufund.worlds.collision import CollisionChecker
from cufund.worlds.world import World, WorldObject

SCENARIOS = [
    "square_lio",
    "square_mocap",
    "square_policy",
    "forest",
    "forest_global",
    "tunnel",
    "vehicle_lio",
    "square_vio",
    "search",
    "fleet_formation:uav2",  # a formation follower, flown in its fleet (it hears the leader's estimate)
    "tunnel+perception=camera,estimator.kind=vio",  # the tunnel on cameras alone: stereo VIO, detector, no LiDAR
]

TRUTH_TYPES = (
    World,
    WorldObject,
    TunnelCourse,
    CollisionChecker,
    Quadrotor,
    Simulator,
    ScenarioBuildContext,
    LidarTruth,
    Sensor,
)
"""What a flight component must not hold (it would see the truth through it)."""


def _simulated(component: Component) -> bool:
    """A simulated sensor model (it may read the truth): its class lives in ``cufund.sensors``."""
    return type(component).__module__.startswith("cufund.sensors.")


def _truth_held(root: Any, limit: int = 200_000) -> list[str]:
    """Paths from ``root`` to the truth objects it reaches through attributes, containers, dataclass fields and
    closures (not through the bus: what it reads there is (a)'s, nor through module globals or classes)."""
    found: list[str] = []
    seen: set[int] = {id(root)}
    todo: list[tuple[Any, str]] = [(root, type(root).__name__)]
    while todo and len(seen) < limit:
        obj, path = todo.pop()
        children: list[tuple[Any, str]] = []
        if isinstance(obj, dict):
            children = [(v, f"{path}[{k!r}]") for k, v in obj.items()]
        elif isinstance(obj, (list, tuple, set, frozenset)) or type(obj).__name__ == "deque":
            children = [(v, f"{path}[{i}]") for i, v in enumerate(obj)]
        elif isinstance(obj, (types.FunctionType, types.MethodType)):
            fn = obj.__func__ if isinstance(obj, types.MethodType) else obj
            if isinstance(obj, types.MethodType):
                children.append((obj.__self__, f"{path}.__self__"))
            for name, cell in zip(fn.__code__.co_freevars, fn.__closure__ or (), strict=True):
                try:
                    children.append((cell.cell_contents, f"{path}<{name}>"))
                except ValueError:  # an empty cell
                    pass
        else:
            attrs: dict[str, Any] = {}
            if hasattr(obj, "__dict__") and not isinstance(obj, type):
                attrs.update(vars(obj))
            for cls in type(obj).__mro__:
                for name in getattr(cls, "__slots__", ()):
                    if isinstance(name, str) and hasattr(obj, name):
                        attrs[name] = getattr(obj, name)
            if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
                attrs.update({f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)})
            children = [(v, f"{path}.{k}") for k, v in attrs.items()]
        for child, child_path in children:
            if isinstance(child, TRUTH_TYPES):  # every path to it
                found.append(f"{child_path}: {type(child).__name__}")
                continue
            if id(child) in seen or child is None:
                continue
            seen.add(id(child))
            if isinstance(child, (Bus, BusView, Subscription, type, types.ModuleType, np.ndarray, str, bytes)):
                continue
            elif isinstance(child, (int, float, complex, bool)):
                continue
            else:
                todo.append((child, child_path))
    return found


@pytest.fixture(scope="module", params=SCENARIOS)
def built(request):
    name, _, vehicle = request.param.partition(":")
    if vehicle:  # one vehicle of a fleet, built and run with the others
        fleet = build_fleet(load_scenario(name))
        fleet.simulator.run(2.0)
        return fleet.vehicle(vehicle).built
    name, _, sets = request.param.partition("+")  # overrides, as --set gives them
    b = build_simulation(load_scenario(name, sets.split(",") if sets else []))
    b.simulator.run(2.0)
    return b


def _flight(built) -> list[tuple[str, Component]]:
    return [(s.name, s.component) for s in built.simulator._slots if not _simulated(s.component)]


def test_flight_software_reads_no_truth_topic(built):
    sim = built.simulator
    flight = _flight(built)
    assert any(n in ("lio", "vio", "imu_propagator") for n, _ in flight)  # it flies on an estimate
    assert any("controller" in n for n, _ in flight)
    for name, c in flight:
        assert not c.reads_truth, f"{name} ({type(c).__name__}) declares itself a truth consumer"
        declared = [str(t) for t in (*c.inputs, *c.optional_inputs)]
        assert not any(is_truth(t) for t in declared), f"{name} declares a truth input: {declared}"
        read = [str(t) for t in sim.views[name].reads]
        assert not any(is_truth(t) for t in read), f"{name} read {read}"
    assert any(is_truth(str(t)) for t in sim.views["imu"].reads)  # the sensor models do: the check can see it


def test_no_flight_part_read_the_world_while_it_was_built(built):
    readers = built.context.world_readers
    flight_readers = [w for w in readers if w != "world" and not w.startswith("sensors.")]
    assert flight_readers == [], f"flight software read the true world at build time: {flight_readers}"
    if built.config.sensors.get("lidar") is not None:
        assert "sensors.lidar" in readers  # the simulated LiDAR does: the recording sees reads


def test_no_flight_component_holds_a_truth_object(built):
    for name, c in _flight(built):
        assert _truth_held(c) == [], name


# ---- the checks themselves fail on a part that cheats -------------------------------------------------------------
@dataclasses.dataclass(frozen=True)
class CheatParams:
    via_accessor: bool = False


class Holder(Component):
    name, rate_hz = "holder", 10.0

    def __init__(self, thing: Any) -> None:
        self.thing = thing
        world = thing["nested"][0]
        self.callback = lambda: world  # a closure keeping it

    def step(self, t, bus):
        pass


def _cheat(p: CheatParams, ctx: BuildContext) -> list[Component]:
    if p.via_accessor:  # the harness's way: the hook asks for the world when it runs, after the build
        ctx.add_metric_hook(lambda result: {"n_objects": len(ctx.truth_world_for_metrics().objects)})
        return []
    world = ctx.world
    ctx.add_metric_hook(lambda result: {"n_objects": len(world.objects)})
    return [Holder({"nested": [world]})]


@pytest.fixture
def cheat_kind():
    register(Kind("mission", "test_cheat_world", CheatParams, _cheat, None, "reads the true world (a test)"))
    yield
    unregister("mission", "test_cheat_world")


@pytest.mark.parametrize("via_accessor", [False, True])
def test_a_part_reading_the_world_is_recorded_and_caught_unless_a_harness_hook(cheat_kind, via_accessor):
    cfg = ScenarioConfig.from_dict(
        {"world": "empty", "mission": {"kind": "test_cheat_world", "via_accessor": via_accessor}, "duration": 1.0}
    )
    b = build_simulation(cfg)
    holders = [c for c in b.simulator.components if isinstance(c, Holder)]
    if via_accessor:
        assert "mission" not in b.context.world_readers and holders == []
        assert b.context.metric_hooks[0](None) == {"n_objects": 1}  # the hook gets the world (its floor) when it runs
    else:
        assert "mission" in b.context.world_readers
        found = _truth_held(holders[0])
        assert any("thing['nested'][0]: World" in f for f in found), found
        assert any("callback<world>: World" in f for f in found), found


def test_the_harness_accessor_is_refused_to_a_part_being_built(cheat_kind):
    """A part cannot take the world through the unrecorded accessor while it is built."""

    def grab(p: CheatParams, ctx: BuildContext) -> list[Component]:
        ctx.truth_world_for_metrics()
        return []

    register(Kind("mission", "test_grab_world", CheatParams, grab, None, "grabs the world at build time (a test)"))
    try:
        cfg = ScenarioConfig.from_dict({"world": "empty", "mission": {"kind": "test_grab_world"}, "duration": 1.0})
        with pytest.raises(RuntimeError, match="truth_world_for_metrics"):
            build_simulation(cfg)
    finally:
        unregister("mission", "test_grab_world")
