"""The simulator asks the Bus and the Quadrotor through public handles (``Bus.has_consumer``,
``Quadrotor.fast_step``) instead of their private fields; what those handles say must follow the objects' state:
a wind function set before or during a run is evaluated at every step (the fast C++ step steps aside), an
overridden ``step`` runs, and a topic has a consumer exactly when it is recorded, subscribed to or logged."""

from __future__ import annotations

import numpy as np

from cufund.core.bus import Bus
from cufund.core.components import Component
from cufund.simulator import Simulator
from cufund.vehicle import presets
from cufund.vehicle.quadrotor import Quadrotor

WIND = np.array([3.0, -1.0, 0.5])


def _hovering(cls: type = Quadrotor) -> Quadrotor:
    quad = cls(presets.cu_astro())
    quad.hover([0.0, 0.0, 10.0])
    return quad


def _final(quad: Quadrotor, components=(), duration: float = 0.2) -> np.ndarray:
    sim = Simulator(quad, physics_rate_hz=1000.0)
    for c in components:
        sim.add(c)
    r = sim.run(duration)
    return np.r_[r.states["p_W"][-1], r.states["v_W"][-1]]


def test_a_wind_function_is_evaluated_at_every_step():
    calls = []

    def wind(t, p_W):
        calls.append(t)
        return WIND

    constant = _hovering()
    constant.set_wind(WIND)
    assert constant.fast_step is not None  # a constant wind is held by the C++ step itself
    function = _hovering()
    function.set_wind(wind)
    assert function.fast_step is None
    x_const, x_fn, x_still = _final(constant), _final(function), _final(_hovering())
    assert len(calls) == 200  # one evaluation per 1 ms step over 0.2 s
    np.testing.assert_array_equal(x_fn, x_const)  # the function's value, held over each step
    assert np.linalg.norm(x_fn[3:] - x_still[3:]) > 1e-3  # and it does push the vehicle
    function.reset()
    assert function.fast_step is not None


class _SetsWind(Component):
    """Sets a wind function on the vehicle at its first run (a disturbance switched on in flight)."""

    rate_hz, inputs, outputs = 10.0, (), ()

    def __init__(self, quad: Quadrotor, fn) -> None:
        self.quad, self.fn, self.done = quad, fn, False

    def reset(self) -> None:
        self.done = False

    def step(self, t: float, bus) -> None:
        if t >= 0.1 and not self.done:
            self.quad.set_wind(self.fn)
            self.done = True


def test_a_wind_function_set_during_the_run_takes_effect_at_once():
    calls = []

    def wind(t, p_W):
        calls.append(round(t, 9))
        return WIND

    quad = _hovering()
    x = _final(quad, [_SetsWind(quad, wind)])
    assert calls[0] == 0.1 and len(calls) == 100  # from the instant it was set to the end
    ref = _hovering()  # the same disturbance switched on by hand between two runs
    Simulator(ref, physics_rate_hz=1000.0).run(0.1)
    ref.set_wind(WIND)
    sim = Simulator(ref, physics_rate_hz=1000.0)
    r = sim.run(0.1)
    np.testing.assert_array_equal(x, np.r_[r.states["p_W"][-1], r.states["v_W"][-1]])


def test_an_overridden_step_runs():
    class Counting(Quadrotor):
        steps = 0

        def step(self, dt, rotor_speed_cmd):
            Counting.steps += 1
            super().step(dt, rotor_speed_cmd)

    x = _final(_hovering(Counting))
    assert Counting.steps == 200
    np.testing.assert_array_equal(x, _final(_hovering()))  # the same physics through the Python layer


def test_has_consumer():
    class Log:
        def write(self, *args) -> None:
            pass

    bus = Bus(record=["/a"])
    assert bus.has_consumer("/a") and not bus.has_consumer("/b")
    bus.subscribe("/b")
    assert bus.has_consumer("/b") and not bus.has_consumer("/c")
    assert Bus(logger=Log()).has_consumer("/c")
    logged = Bus(logger=Log(), log_topics=["/d"])
    assert logged.has_consumer("/d") and not logged.has_consumer("/c")
