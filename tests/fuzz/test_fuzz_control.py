"""Fuzz: the geometric control bindings and control allocation."""

from __future__ import annotations

import numpy as np
from fuzz_support import arrays, expect_good, floats_any, fuzz_settings, scalars
from hypothesis import given
from hypothesis import strategies as st

UNIT_Q = np.array([1.0, 0.0, 0.0, 0.0])
J = np.diag([1.43e-5, 1.43e-5, 2.89e-5])


@fuzz_settings
@given(
    which=st.sampled_from(["J", "mass", "q_WB", "w_B", "F_W", "k_R", "yaw"]),
    value=st.one_of(arrays([(3, 3), (3,), (4,), (2, 2)]), scalars()),
)
def test_geometric_from_force(server, which, value):
    args = {
        "J": J,
        "mass": 0.03,
        "k_R": np.full(3, 0.01),
        "k_W": np.full(3, 0.001),
        "q_WB": UNIT_Q,
        "w_B": np.zeros(3),
        "F_W": np.array([0.0, 0.0, 0.3]),
        "j_W": np.zeros(3),
        "yaw": 0.0,
        "yaw_rate": 0.0,
    }
    args[which] = value
    call = "cufund._core.control.geometric_from_force(J, mass, k_R, k_W, q_WB, w_B, F_W, j_W, yaw, yaw_rate)"
    outcome, detail = server.run(
        "control",
        "",
        "result = " + call + "\nresult = np.concatenate([[result[0]], result[1], result[2]])",
        args,
        check="np.isfinite(result).all()",
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(
    which=st.sampled_from(["J", "q_WB", "q_WB_d", "thrust", "yaw_rate"]),
    value=st.one_of(arrays([(3, 3), (4,), (3,)]), scalars()),
)
def test_geometric_from_attitude(server, which, value):
    args = {
        "J": J,
        "k_R": np.full(3, 0.01),
        "k_W": np.full(3, 0.001),
        "q_WB": UNIT_Q,
        "w_B": np.zeros(3),
        "q_WB_d": UNIT_Q,
        "thrust": 0.3,
        "yaw_rate": 0.0,
    }
    args[which] = value
    call = "cufund._core.control.geometric_from_attitude(J, k_R, k_W, q_WB, w_B, q_WB_d, thrust, yaw_rate)"
    outcome, detail = server.run(
        "control",
        "",
        "result = " + call + "\nresult = np.concatenate([[result[0]], result[1], result[2]])",
        args,
        check="np.isfinite(result).all()",
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(thrust=st.one_of(floats_any(), scalars()), torque=arrays([(3,), (4,)]))
def test_allocation(server, thrust, torque):
    outcome, detail = server.run(
        "control",
        "a = cufund._core.control.ControlAllocator(cufund.vehicle.presets.crazyflie().to_core())",
        "result = a.allocate(thrust, torque)\nresult = np.concatenate([result[0], result[1]])",
        {"thrust": thrust, "torque": torque},
        check="np.isfinite(result).all()",
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(
    goal=arrays([(3,), (2,)], st.one_of(st.floats(-1e17, 1e17), floats_any())),
    v_max=st.one_of(st.just(1.0), scalars()),
    a_max=st.one_of(st.just(2.0), floats_any()),
)
def test_point_to_point_move(server, goal, v_max, a_max):
    # ruckig raises its own RuckigError for far goals (a waypoint at 1.5e16 m): it must arrive as ValueError.
    code = """
from cufund.planning.point_to_point import JerkLimitedMove
move = JerkLimitedMove(np.zeros(3), goal, v_max=v_max, a_max=a_max)
s = move.sample(np.linspace(0.0, move.duration, 5))
result = np.concatenate([np.ravel(s.p_W), [move.duration]])
"""
    outcome, detail = server.run(
        "planning", "", code, {"goal": goal, "v_max": v_max, "a_max": a_max}, check="np.isfinite(result).all()"
    )
    expect_good(outcome, detail)
