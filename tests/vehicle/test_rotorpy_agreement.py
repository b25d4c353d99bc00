"""Our Crazyflie against RotorPy's Multirotor, the reference implementation, on one open-loop flight.

Both models integrate the same equations: thrust k_f w^2, yaw moment k_m w^2 with RotorPy's rotor
directions, rotor drag -w_i K (v_air + w x r_i) at each hub, quadratic body drag, first-order motor lag.
RotorPy integrates with scipy's RK45 at rtol 1e-11, ours with RK4 at 1 ms, so the only differences
are integration error (RK4: ~1e-9 relative over this flight) and rounding. A convention error
(rotor order, spin direction, drag frame, quaternion order) gives millimetres within 0.1 s, so the
tolerances (1e-8 m, 1e-7 m/s, 1e-6 rad/s, 1e-5 rad/s) separate the two by orders of magnitude.
"""

import dataclasses

import numpy as np

import cufund

ROTORPY_FROM_PX4 = [2, 0, 3, 1]  # RotorPy r1..r4 (FL, FR, RR, RL) are PX4 rotors 3, 1, 4, 2


def test_open_loop_flight_agrees_with_rotorpy():
    from rotorpy.vehicles.crazyflie_params import quad_params
    from rotorpy.vehicles.multirotor import Multirotor

    params = dataclasses.replace(cufund.vehicle.presets.crazyflie(), gravity=9.81)  # RotorPy's g
    q0_wxyz = np.array([np.cos(0.1), 0.6 * np.sin(0.1), 0.8 * np.sin(0.1), 0.0])
    init = {
        "x": np.array([0.2, -0.1, 1.0]),
        "v": np.array([0.3, -0.2, 0.1]),
        "q": np.r_[q0_wxyz[1:], q0_wxyz[0]],
        "w": np.array([0.5, -0.4, 0.3]),
        "wind": np.array([1.0, 0.5, -0.2]),
        "rotor_speeds": np.full(4, 1800.0),
    }
    ref = Multirotor(
        quad_params,
        initial_state=init,
        control_abstraction="cmd_motor_speeds",
        aero=True,
        enable_ground=False,
        integrator_kwargs={"method": "RK45", "rtol": 1e-11, "atol": 1e-12},
    )
    quad = cufund.Quadrotor(params, wind=init["wind"])
    s = quad.state
    s.p[:], s.v[:], s.q[:], s.w[:], s.rotor_speeds[:] = init["x"], init["v"], q0_wxyz, init["w"], 1800.0

    state = {k: v.copy() for k, v in init.items()}
    dt, w_h = 0.01, params.hover_rotor_speed
    freqs, phases = np.array([1.0, 1.3, 1.7, 2.1]), np.arange(4.0)
    worst = np.zeros(4)
    for k in range(100):
        cmd = w_h * (1 + 0.03 * np.sin(2 * np.pi * freqs * k * dt + phases))
        state = ref.step(state, {"cmd_motor_speeds": cmd[ROTORPY_FROM_PX4]}, dt)
        quad.step(dt, cmd)
        q_ref = np.r_[state["q"][3], state["q"][:3]]
        worst = np.maximum(
            worst,
            [
                np.linalg.norm(state["x"] - s.p),
                np.linalg.norm(state["v"] - s.v),
                np.linalg.norm(state["w"] - s.w),
                min(np.linalg.norm(q_ref - s.q), np.linalg.norm(q_ref + s.q)),
            ],
        )
        np.testing.assert_allclose(state["rotor_speeds"], s.rotor_speeds[ROTORPY_FROM_PX4], rtol=0, atol=1e-5)
    # The flight goes somewhere: it turns and drifts by decimetres, not a trivial hover.
    assert np.linalg.norm(s.p - init["x"]) > 0.3
    assert worst[0] < 1e-8, f"position differs by {worst[0]:.3e} m"
    assert worst[1] < 1e-7, f"velocity differs by {worst[1]:.3e} m/s"
    assert worst[2] < 1e-6, f"body rate differs by {worst[2]:.3e} rad/s"
    assert worst[3] < 1e-8, f"attitude differs by {worst[3]:.3e}"
