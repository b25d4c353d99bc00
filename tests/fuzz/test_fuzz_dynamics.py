"""Fuzz: vehicle parameters, Quadrotor / QuadrotorBatch stepping, state writes, collision world."""

from __future__ import annotations

import numpy as np
from fuzz_support import Code, arrays, expect_good, floats_any, fuzz_settings, scalars
from hypothesis import given
from hypothesis import strategies as st

PARAM_FIELDS = [
    "mass",
    "inertia",
    "arm_length",
    "k_f",
    "c_m",
    "tau_m",
    "rotor_speed_max",
    "rotor_speed_min",
    "layout",
    "rotor_drag_xy",
    "rotor_drag_z",
    "body_drag",
    "gravity",
    "ground_plane",
    "max_integration_step",
]

FLY = """
import dataclasses
params = dataclasses.replace(cufund.vehicle.presets.crazyflie(), **kw)
quad = cufund.Quadrotor(params)
quad.hover(np.array([0.0, 0.0, 1.0]))
for _ in range(20):
    quad.step(1e-3, np.full(4, params.hover_rotor_speed * 1.01))
result = quad.state.as_vector()
"""


@fuzz_settings
@given(
    field=st.sampled_from(PARAM_FIELDS),
    value=st.one_of(scalars(), arrays([(3,), (3, 3), (2, 2), (9,)]), st.sampled_from(["x", "+", "X", ""])),
)
def test_params_fields(server, field, value):
    outcome, detail = server.run("params", "", FLY, {"kw": {field: value}}, check="np.isfinite(result).all()")
    expect_good(outcome, detail)


@fuzz_settings
@given(
    dt=st.one_of(scalars(), st.sampled_from([1e5, 1e9, 1e-300, 5e-324])),
    cmd=arrays([(4,), (1, 4), (3,), (4, 1), ()], st.floats(-1e6, 1e6) | floats_any()),
)
def test_quadrotor_step(server, dt, cmd):
    outcome, detail = server.run(
        "dynamics",
        "quad = cufund.Quadrotor(cufund.vehicle.presets.crazyflie())",
        "quad.step(dt, cmd)\nresult = quad.state.as_vector()",
        {"dt": dt, "cmd": cmd},
        check="np.isfinite(result).all()",
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(n=st.one_of(scalars(), st.sampled_from([2**32, 2**32 + 1, 2**40, 2**24 + 1, 100_000_000])))
def test_batch_size(server, n):
    outcome, detail = server.run(
        "dynamics", "", "cufund.QuadrotorBatch(cufund.vehicle.presets.crazyflie(), n).n", {"n": n}
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(
    view=st.sampled_from(["p", "v", "q", "w", "rotor_speeds", "wind_W", "force_ext_W", "torque_ext_B"]),
    value=st.one_of(floats_any(), st.floats(-1e12, 1e12)),
    t=st.one_of(floats_any(), scalars()),
)
def test_state_writes_then_step(server, view, value, t):
    code = f"""
b = cufund.QuadrotorBatch(cufund.vehicle.presets.crazyflie(), 3)
b.hover(np.array([0.0, 0.0, 1.0]))
b.{view}[1, 0] = value
try:
    b.t = t
except (TypeError, ValueError):
    pass
b.step(1e-3, np.full((3, 4), 1500.0))
result = np.concatenate([b.p.ravel(), b.v.ravel(), b.q.ravel(), b.w.ravel(), [b.t]])
"""
    outcome, detail = server.run("dynamics", "", code, {"value": value, "t": t}, check="np.isfinite(result).all()")
    expect_good(outcome, detail)


@fuzz_settings
@given(
    vertices=st.one_of(
        arrays([(4, 3), (3, 3), (0, 3), (4, 2)]), st.just(Code("np.broadcast_to(np.float64([0, 0, 0]), (2**33, 3))"))
    ),
    triangles=st.one_of(
        arrays([(2, 3), (1, 3), (0, 3)], st.integers(-5, 2**40).map(float)),
        st.just(np.array([[0, 1, 2], [0, 2, 3]])),
        st.just(Code("np.broadcast_to(np.int64([0, 1, 2]), (2**33, 3))")),
    ),
    p=arrays([(3,)]),
    q=arrays([(4,)]),
    margin=scalars(),
)
def test_collision_world(server, vertices, triangles, p, q, margin):
    code = """
w = cufund._core.dynamics.CollisionWorld()
w.add_mesh(vertices, triangles)
w.set_vehicle_sphere(0.2)
result = w.check(p, q, margin)
"""
    outcome, detail = server.run(
        "collision",
        "",
        code,
        {"vertices": vertices, "triangles": triangles, "p": p, "q": q, "margin": margin},
        check="result is None or np.isfinite(result['distance'])",
    )
    expect_good(outcome, detail)
