"""The fleet's batched physics step: ``step_batches`` integrates several plants in one call exactly as each one's
own ``step`` does, and a fleet whose vehicles step on different schedules (other rates, a latency off the physics
grid, so their steps are split at different instants) runs bit for bit as with each simulator stepping its own
plant, and each far-apart vehicle as it runs alone."""

from __future__ import annotations

import weakref

import numpy as np
import pytest

from cufund import _core
from cufund.scenarios.build import run_scenario
from cufund.scenarios.fleet import build_fleet, vehicle_scenario
from cufund.scenarios.schema import ScenarioConfig, load_scenario
from cufund.vehicle import QuadrotorBatch, presets


def _moving(n: int, seed: int) -> QuadrotorBatch:
    b = QuadrotorBatch(presets.crazyflie(), n)
    rng = np.random.default_rng(seed)
    b.p[:] = rng.normal(size=(n, 3)) + [0, 0, 5]
    b.v[:] = rng.normal(size=(n, 3))
    q = rng.normal(size=(n, 4))
    b.q[:] = q / np.linalg.norm(q, axis=1, keepdims=True)
    b.w[:] = rng.normal(size=(n, 3))
    b.rotor_speeds[:] = b.params.hover_rotor_speed * (1 + 0.1 * rng.normal(size=(n, 4)))
    return b


@pytest.mark.parametrize("nthreads", [1, 2])
def test_step_batches_is_each_batchs_own_step_bit_for_bit(nthreads):
    sizes, dts = (1, 3, 1, 2), np.array([1e-3, 2.5e-4, 7e-3, 1e-3])
    together = [_moving(n, k) for k, n in enumerate(sizes)]
    alone = [_moving(n, k) for k, n in enumerate(sizes)]
    rng = np.random.default_rng(7)
    for _ in range(20):
        cmds = [together[0].params.hover_rotor_speed * (1 + 0.2 * rng.normal(size=(n, 4))) for n in sizes]
        _core.dynamics.step_batches([b._core for b in together], dts, np.concatenate(cmds), nthreads)
        for b, dt, cmd in zip(alone, dts, cmds, strict=True):
            b._core.step(dt, cmd, 1)
    for a, b in zip(together, alone, strict=True):
        for field in ("p", "v", "q", "w", "rotor_speeds", "accel_W", "alpha_B"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), field
        assert a.t == b.t
    assert together[2].t == pytest.approx(20 * 7e-3)  # each its own dt


def test_step_batches_errors_name_the_batch_and_step_the_others():
    a, b = _moving(1, 0), _moving(1, 1)
    p0 = a.p.copy()
    cmd = np.full((2, 4), a.params.hover_rotor_speed)
    cmd[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"batches\[1\]: rotor_speed_cmd must be finite .* rotor 3"):
        _core.dynamics.step_batches([a._core, b._core], np.array([1e-3, 1e-3]), cmd, 1)
    assert not np.array_equal(a.p, p0)  # the good one was stepped
    with pytest.raises(ValueError, match=r"batches\[0\]: dt must be a finite number > 0"):
        _core.dynamics.step_batches([a._core], np.array([-1.0]), cmd[:1], 1)
    with pytest.raises(ValueError, match="batches must be distinct"):
        _core.dynamics.step_batches([a._core, a._core], np.array([1e-3, 1e-3]), cmd, 1)
    with pytest.raises(TypeError, match=r"batches\[1\] must be a QuadrotorBatch, got str"):
        _core.dynamics.step_batches([a._core, "b"], np.array([1e-3, 1e-3]), cmd, 1)
    with pytest.raises(ValueError, match=r"rotor_speed_cmd must have shape \(2, 4\)"):
        _core.dynamics.step_batches([a._core, b._core], np.array([1e-3, 1e-3]), cmd[:1], 1)


def test_step_batches_holds_each_batch_for_the_call():
    """A sequence may make its items on access: each batch must stay alive until it is stepped (the call holds a
    reference to each, not a pointer into an item already released; without it, the batch was freed before the step
    and the step wrote into freed memory)."""
    params = presets.crazyflie()
    refs: list[weakref.ref] = []
    alive_at_dt: list[bool] = []

    class Fresh:  # a sequence whose items exist only while someone holds them
        def __len__(self) -> int:
            return 2

        def __getitem__(self, k: int):
            if not 0 <= k < 2:
                raise IndexError(k)
            core = _core.dynamics.QuadrotorBatch(params.to_core(), 1)
            refs.append(weakref.ref(core))
            return core

    class Dt:  # read after the batches: are they still alive then?
        def __array__(self, dtype=None, copy=None):
            alive_at_dt.append(all(r() is not None for r in refs))
            return np.array([1e-3, 1e-3])

    cmd = np.full((2, 4), params.hover_rotor_speed)
    _core.dynamics.step_batches(Fresh(), Dt(), cmd, 1)
    assert len(refs) == 2 and alive_at_dt == [True]
    assert all(r() is None for r in refs)  # and released after the call


def _square_at(name, x, y, **overrides):
    wp = [[x, y, 1.5], [x + 1, y, 1.5], [x + 1, y + 1, 1.5], [x, y + 1, 1.5], [x, y, 1.5]]
    return {"name": name, "start": {"p": [x, y, 0.0]}, "trajectory": {"waypoints": wp}, **overrides}


def _mixed_schedules() -> ScenarioConfig:
    data = load_scenario("square_mocap").to_dict()
    pose = dict(data["sensors"]["pose"])
    vehicles = [
        _square_at("a", 0, 0),
        # motion capture at 90 Hz, 3.7 ms late: its events fall between the 1 kHz physics nodes
        _square_at("b", 40, 0, sensors={**data["sensors"], "pose": {**pose, "rate_hz": 90.0, "latency_s": 0.0037}}),
        # motion capture at 120 Hz, 1.1 ms late
        _square_at("c", 0, 40, sensors={**data["sensors"], "pose": {**pose, "rate_hz": 120.0, "latency_s": 0.0011}}),
    ]
    data.update(name="fleet_mixed", duration=4.0, vehicles=vehicles, downwash=True)
    return ScenarioConfig.from_dict(data)


def test_batched_fleet_with_different_schedules_is_bit_for_bit():
    cfg = _mixed_schedules()
    batched, each = build_fleet(cfg), build_fleet(cfg)
    each.simulator.batched_physics = False
    assert batched.simulator.batched_physics
    rb, re_ = batched.run(), each.run()
    assert batched.simulator.physics_seconds > 0 and each.simulator.physics_seconds == 0
    for name in ("a", "b", "c"):
        a, b = rb.runs[name].result.states, re_.runs[name].result.states
        assert len(a["t"]) > 3000
        for k in a:
            assert np.array_equal(a[k], b[k]), (name, k)
    # and each far-apart vehicle is its run alone (the one with off-grid events included)
    alone = run_scenario(vehicle_scenario(cfg, "b"))
    for k, v in alone.result.states.items():
        assert np.array_equal(v, rb.runs["b"].result.states[k]), k


def test_batched_physics_flag_is_checked():
    from cufund.simulator.fleet import FleetSimulator

    fleet = build_fleet(_mixed_schedules())
    with pytest.raises(ValueError, match="batched_physics must be True or False, got 1"):
        FleetSimulator(fleet.simulator.members, batched_physics=1)  # type: ignore[arg-type]


def test_a_batched_fleets_failing_step_names_the_vehicle():
    """A step the integrator refuses (here a NaN command) is raised naming the fleet's vehicle, not the row of the
    round's step_batches call."""
    from cufund.simulator import Simulator
    from cufund.simulator.fleet import FleetMember, FleetSimulator
    from cufund.vehicle.quadrotor import Quadrotor

    def hovering(p_W):
        quad = Quadrotor(presets.crazyflie())
        quad.hover(np.array(p_W, dtype=float))
        return quad

    fleet = FleetSimulator(
        [FleetMember(name, Simulator(hovering([9.0 * k, 0.0, 5.0]))) for k, name in enumerate(("a", "b", "c"))]
    )
    fleet.reset()
    fleet.members[1].simulator._cmd[2] = np.nan  # b's held command (no controller replaces it)
    with pytest.raises(ValueError, match=r"^vehicle b: rotor_speed_cmd must be finite .* rotor 3"):
        fleet.advance_to(0.01)
    assert fleet.members[2].simulator.vehicle.t > 0  # the others of the round were stepped
