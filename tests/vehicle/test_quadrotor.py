"""The Python surface of the dynamics: shapes, views, batch/single equivalence, wind, bad input."""

import numpy as np
import pytest

import cufund


def test_single_vehicle_state_shapes_and_keywords(crazyflie):
    quad = cufund.Quadrotor(params=crazyflie)
    s = quad.state
    assert [a.shape for a in (s.p, s.v, s.q, s.w, s.rotor_speeds)] == [(3,), (3,), (4,), (3,), (4,)]
    np.testing.assert_array_equal(s.q, [1, 0, 0, 0])
    quad.step(dt=1e-3, rotor_speed_cmd=np.zeros(4))
    assert quad.t == pytest.approx(1e-3)
    assert s.as_vector().shape == (17,)


def test_state_arrays_are_views_into_the_simulation(crazyflie):
    quad = cufund.Quadrotor(crazyflie)
    quad.state.p[:] = (1.0, 2.0, 3.0)
    snapshot = quad.state.copy()
    quad.step(0.1, np.zeros(4))  # free fall updates the same arrays
    assert quad.state.p[2] < 3.0
    assert snapshot.p[2] == 3.0


def test_batch_shapes_and_zero_copy_views(crazyflie):
    b = cufund.QuadrotorBatch(crazyflie, n=5)
    for name, k in [
        ("p", 3),
        ("v", 3),
        ("q", 4),
        ("w", 3),
        ("rotor_speeds", 4),
        ("wind_W", 3),
        ("force_ext_W", 3),
        ("torque_ext_B", 3),
    ]:
        a = getattr(b, name)
        assert a.shape == (5, k) and a.dtype == np.float64
        assert not a.flags.owndata  # a view onto the C++ buffer
    p_view = b.p
    b.p[2] = (0.0, 0.0, 7.0)
    assert p_view[2, 2] == 7.0


def test_batch_equals_single_vehicles_bit_for_bit(crazyflie, rng):
    n = 13
    batch = cufund.QuadrotorBatch(crazyflie, n)
    singles = [cufund.Quadrotor(crazyflie) for _ in range(n)]
    batch.p[:] = rng.uniform(-1, 1, (n, 3)) + (0, 0, 2)
    batch.v[:] = rng.uniform(-1, 1, (n, 3))
    q = rng.normal(size=(n, 4))
    batch.q[:] = q / np.linalg.norm(q, axis=1, keepdims=True)
    batch.w[:] = rng.uniform(-3, 3, (n, 3))
    batch.rotor_speeds[:] = rng.uniform(1500, 2000, (n, 4))
    for i, s in enumerate(singles):
        for name in ("p", "v", "q", "w", "rotor_speeds"):
            getattr(s.state, name)[:] = getattr(batch, name)[i]
    cmds = rng.uniform(1400, 2200, (200, n, 4))
    for cmd in cmds:
        batch.step(2e-3, cmd, nthreads=2)
        for i, s in enumerate(singles):
            s.step(2e-3, cmd[i])
    for i, s in enumerate(singles):
        assert batch.p[i].tobytes() == s.state.p.tobytes()
        assert batch.q[i].tobytes() == s.state.q.tobytes()
        assert batch.w[i].tobytes() == s.state.w.tobytes()
        assert batch.rotor_speeds[i].tobytes() == s.state.rotor_speeds.tobytes()


def test_results_do_not_depend_on_thread_count(crazyflie, rng):
    n = 3000  # several blocks, so both threads get work
    cmd = crazyflie.hover_rotor_speed * (1 + 0.05 * rng.standard_normal((n, 4)))
    finals = []
    for threads in (1, 2):
        b = cufund.QuadrotorBatch(crazyflie, n)
        b.hover(np.c_[np.zeros((n, 2)), np.full(n, 5.0)])
        for _ in range(100):
            b.step(1e-3, cmd, nthreads=threads)
        finals.append(np.concatenate([b.p, b.q, b.w], axis=1).copy())
    assert finals[0].tobytes() == finals[1].tobytes()


def test_wind_function_is_sampled_at_step_start(crazyflie):
    seen = []

    def wind(t, p_W):
        seen.append((t, p_W.copy()))
        return np.array([3.0, 0.0, 0.0])

    quad = cufund.Quadrotor(crazyflie, wind=wind)
    quad.hover((0.0, 0.0, 1.0))
    for _ in range(50):
        quad.step(1e-3, np.full(4, crazyflie.hover_rotor_speed))
    assert len(seen) == 50 and seen[0][0] == 0.0 and seen[-1][0] == pytest.approx(0.049)
    assert seen[0][1].shape == (1, 3)
    np.testing.assert_array_equal(quad.wind_W, [3.0, 0.0, 0.0])
    assert quad.state.v[0] > 0  # rotor drag pushes it downwind


def test_external_force_against_analytic_drift_with_rotor_drag(crazyflie):
    quad = cufund.Quadrotor(crazyflie)
    quad.hover((0.0, 0.0, 1.0))
    a = 2.0
    quad.force_ext_W[:] = (0.0, crazyflie.mass * a, 0.0)
    t = 0.5
    quad.step(t, np.full(4, crazyflie.hover_rotor_speed))
    # Level hover: the four rotors' drag is linear, -b m v with b = 4 w_h k_d / m, so
    # y(t) = (a / b) (t - (1 - exp(-b t)) / b).
    b = 4 * crazyflie.hover_rotor_speed * crazyflie.rotor_drag_xy / crazyflie.mass
    expected = a / b * (t - (1 - np.exp(-b * t)) / b)
    assert quad.state.p[1] == pytest.approx(expected, rel=1e-9)
    assert abs(expected - a * t**2 / 2) > 1e-3  # the drag term matters at this tolerance


def test_ground_contact_in_python(crazyflie):
    quad = cufund.Quadrotor(crazyflie)
    quad.state.p[2] = 0.3
    for _ in range(500):
        quad.step(2e-3, np.zeros(4))
        assert quad.state.p[2] >= 0.0
    assert quad.state.p[2] == 0.0 and np.all(quad.state.v == 0.0)


# ---- bad input ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("cmd", "message"),
    [
        (np.zeros(3), r"rotor_speed_cmd must have shape \(4,\), got \(3,\)"),
        (np.zeros((2, 4)), r"rotor_speed_cmd must have shape \(1, 4\), got \(2, 4\)"),
        (np.array([1, 2, 3, np.nan]), "rotor_speed_cmd must be finite .* vehicle 0, rotor 4"),
        (np.array([1, np.inf, 3, 4]), "rotor_speed_cmd must be finite .* vehicle 0, rotor 2"),
        (np.zeros(4, dtype=complex), "rotor_speed_cmd must have a real numeric dtype"),
        (np.array(["a", "b", "c", "d"]), "rotor_speed_cmd must have a real numeric dtype"),
        ("fast", "rotor_speed_cmd must have a real numeric dtype"),
    ],
)
def test_bad_commands_raise(crazyflie, cmd, message):
    quad = cufund.Quadrotor(crazyflie)
    before = quad.state.as_vector()
    with pytest.raises(ValueError, match=message):
        quad.step(1e-3, cmd)
    np.testing.assert_array_equal(quad.state.as_vector(), before)  # nothing advanced


def test_integer_commands_are_accepted(crazyflie):
    quad = cufund.Quadrotor(crazyflie)
    quad.step(1e-3, np.array([1000, 1000, 1000, 1000]))
    assert quad.state.rotor_speeds[0] > 0


def test_batch_command_shape_is_checked(crazyflie):
    b = cufund.QuadrotorBatch(crazyflie, 3)
    with pytest.raises(ValueError, match=r"rotor_speed_cmd must have shape \(3, 4\), got \(4,\)"):
        b.step(1e-3, np.zeros(4))
    with pytest.raises(ValueError, match=r"vehicle 2, rotor 1"):
        b.step(1e-3, np.array([[0.0] * 4, [0.0] * 4, [np.nan, 0, 0, 0]]))


@pytest.mark.parametrize("dt", [0.0, -1e-3, float("nan"), float("inf")])
def test_bad_time_step_raises(crazyflie, dt):
    with pytest.raises(ValueError, match="dt must be a finite number > 0"):
        cufund.Quadrotor(crazyflie).step(dt, np.zeros(4))


@pytest.mark.parametrize("n", [0, -3, 2.5, True, 2**32 + 1, 2**59, 2**70])
def test_bad_batch_size_raises(crazyflie, n):
    with pytest.raises(ValueError, match=r"n must be an integer in \[1, 2\^32\]"):
        cufund.QuadrotorBatch(crazyflie, n)


def test_core_batch_rejects_sizes_whose_state_would_overflow(crazyflie):
    from cufund import _core

    with pytest.raises(ValueError, match=r"n must be an integer in \[1, 2\^32\]"):
        _core.dynamics.QuadrotorBatch(crazyflie.to_core(), 2**62)


def test_core_batch_params_are_a_copy(crazyflie):
    from cufund import _core

    b = _core.dynamics.QuadrotorBatch(crazyflie.to_core(), 1)
    b.params.mass = -1.0  # changes a copy, not the running batch
    assert b.params.mass == crazyflie.mass


@pytest.mark.parametrize(
    ("wind", "message"),
    [
        (np.zeros(2), r"wind must have shape \(3,\) or \(1, 3\)"),
        (np.array([np.nan, 0, 0]), "wind must be finite"),
    ],
)
def test_bad_wind_raises(crazyflie, wind, message):
    with pytest.raises(ValueError, match=message):
        cufund.Quadrotor(crazyflie, wind=wind)


def test_bad_wind_function_output_raises(crazyflie):
    quad = cufund.Quadrotor(crazyflie, wind=lambda t, p: np.array([np.nan, 0.0, 0.0]))
    with pytest.raises(ValueError, match=r"wind\(t, p_W\) must be finite"):
        quad.step(1e-3, np.zeros(4))


def test_params_type_is_checked():
    with pytest.raises(TypeError, match="params must be a cufund.QuadrotorParams"):
        cufund.Quadrotor({"mass": 1.0})  # type: ignore[arg-type]


def test_reported_accelerations_match_central_differences(crazyflie, rng):
    """accel_W and alpha_B are the model's derivatives, not differences: check them against the latter."""
    quad = cufund.Quadrotor(crazyflie)
    quad.hover((0.0, 0.0, 2.0))
    quad.state.w[:] = (1.0, -0.5, 0.3)
    cmd = crazyflie.hover_rotor_speed * np.array([1.05, 0.97, 1.02, 0.99])
    h = 1e-4
    quad.step(0.05, cmd)
    v0, w0 = quad.state.v.copy(), quad.state.w.copy()
    quad.step(h, cmd)
    a_mid, alpha_mid = quad.accel_W.copy(), quad.alpha_B.copy()
    quad.step(h, cmd)
    np.testing.assert_allclose(a_mid, (quad.state.v - v0) / (2 * h), rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(alpha_mid, (quad.state.w - w0) / (2 * h), rtol=1e-5, atol=1e-5)
    assert np.linalg.norm(alpha_mid) > 1.0  # a real rotation is going on


# --- Pickling, thread safety, fork safety and limits (issues 10 and 11) ---------------------------


def _fly(quad, steps, k0=0):
    """A deterministic, varying command sequence (so that a wrong restore shows)."""
    hover = quad.params.hover_rotor_speed
    for k in range(k0, k0 + steps):
        quad.step(1e-3, hover * (1.0 + 0.05 * np.sin(0.01 * k + np.arange(4))))


def test_quadrotor_pickles_and_continues_bit_for_bit(crazyflie):
    import pickle

    quad = cufund.Quadrotor(crazyflie, wind=np.array([0.5, -0.2, 0.0]))
    quad.hover(np.array([1.0, 2.0, 3.0]))
    quad.force_ext_W[:] = (0.01, 0.0, -0.02)
    _fly(quad, 150)
    copy = pickle.loads(pickle.dumps(quad))
    assert copy.t == quad.t and copy.params == quad.params
    assert np.array_equal(copy.state.as_vector(), quad.state.as_vector())
    for name in ("wind_W", "force_ext_W", "torque_ext_B", "accel_W", "alpha_B"):
        assert np.array_equal(getattr(copy, name), getattr(quad, name)), name
    _fly(quad, 200, 150)
    _fly(copy, 200, 150)
    assert copy.t == quad.t
    assert copy.state.as_vector().tobytes() == quad.state.as_vector().tobytes()  # bit for bit
    # The copy owns its state: stepping it does not move the original.
    before = quad.state.as_vector()
    _fly(copy, 5)
    assert np.array_equal(quad.state.as_vector(), before)


def test_quadrotor_batch_pickles_and_continues_bit_for_bit(crazyflie, rng):
    import pickle

    b = cufund.QuadrotorBatch(crazyflie, 7)
    b.hover(rng.uniform(-1, 1, (7, 3)) + [0, 0, 2])
    cmd = crazyflie.hover_rotor_speed * (1 + 0.1 * rng.standard_normal((7, 4)))
    for _ in range(50):
        b.step(1e-3, cmd)
    c = pickle.loads(pickle.dumps(b))
    for _ in range(50):
        b.step(1e-3, cmd)
        c.step(1e-3, cmd)
    assert c.t == b.t and c.n == b.n
    for name in cufund.QuadrotorBatch._ROWS:
        assert getattr(c, name).tobytes() == getattr(b, name).tobytes(), name


def test_batch_time_and_state_writes_must_be_finite(crazyflie):
    b = cufund.QuadrotorBatch(crazyflie, 3)
    with pytest.raises(ValueError, match="t must be finite"):
        b.t = float("nan")
    with pytest.raises(TypeError, match="t must be a real number"):
        b.t = "1.0"
    assert b.t == 0.0
    b.v[2, 1] = np.inf
    with pytest.raises(ValueError, match="state v of vehicle 2 must be finite"):
        b.step(1e-3, np.zeros((3, 4)))
    b.v[2, 1] = 0.0
    b.torque_ext_B[0, 2] = np.nan
    with pytest.raises(ValueError, match="state torque_ext_B of vehicle 0 must be finite"):
        b.step(1e-3, np.zeros((3, 4)))
    b.torque_ext_B[0, 2] = 0.0
    b.q[1] = 0.0
    with pytest.raises(ValueError, match="state q of vehicle 1 must be a non-zero quaternion"):
        b.step(1e-3, np.zeros((3, 4)))
    assert b.t == 0.0  # nothing advanced


@pytest.mark.parametrize(
    ("dt", "nthreads", "error", "message"),
    [
        ("0.001", 0, TypeError, "dt must be a real number, got str"),
        (None, 0, TypeError, "dt must be a real number, got NoneType"),
        (1e-3, "2", TypeError, "nthreads must be an integer, got str"),
        (1e-3, -1, ValueError, "nthreads must be >= 0"),
    ],
)
def test_step_arguments_are_named_in_errors(crazyflie, dt, nthreads, error, message):
    b = cufund.QuadrotorBatch(crazyflie, 2)
    with pytest.raises(error, match=message):
        b.step(dt, np.zeros((2, 4)), nthreads)


def test_step_dt_is_limited_and_the_limit_is_configurable(crazyflie):
    import cufund.core.limits

    quad = cufund.Quadrotor(crazyflie)
    with pytest.raises(ValueError, match=r"dt must need at most 1000000 integration sub-steps"):
        quad.step(1e5, np.zeros(4))  # 1e8 sub-steps: 16 s before the limit
    with cufund.core.limits.override(step_max_substeps=10):
        with pytest.raises(ValueError, match="at most 10 integration sub-steps"):
            quad.step(0.011, np.zeros(4))
        quad.step(0.010, np.zeros(4))
    assert quad.t == pytest.approx(0.010)
    assert cufund.core.limits.current().step_max_substeps == 1_000_000


def test_batch_size_is_limited_and_the_limit_is_configurable(crazyflie):
    import cufund.core.limits

    with cufund.core.limits.override(batch_max_size=8):
        with pytest.raises(ValueError, match=r"n must be at most batch_max_size = 8"):
            cufund.QuadrotorBatch(crazyflie, 9)
        assert cufund.QuadrotorBatch(crazyflie, 8).n == 8
    with pytest.raises(ValueError, match=r"n must be at most batch_max_size = 16777216"):
        cufund.QuadrotorBatch(crazyflie, 2**25)


@pytest.mark.parametrize(("n", "nthreads"), [(200, 0), (4096, 1)])
def test_one_batch_stepped_from_four_threads_equals_the_same_steps_in_sequence(crazyflie, rng, n, nthreads):
    import threading

    p0 = rng.uniform(-5, 5, (n, 3)) + [0, 0, 10]
    cmd = crazyflie.hover_rotor_speed * (1 + 0.05 * rng.standard_normal((n, 4)))
    shared, serial = cufund.QuadrotorBatch(crazyflie, n), cufund.QuadrotorBatch(crazyflie, n)
    shared.hover(p0)
    serial.hover(p0)
    steps, threads = 20, 4
    barrier = threading.Barrier(threads)

    def worker():
        barrier.wait()
        for _ in range(steps):
            shared.step(1e-3, cmd, nthreads)

    pool = [threading.Thread(target=worker) for _ in range(threads)]
    for t in pool:
        t.start()
    for t in pool:
        t.join()
    for _ in range(steps * threads):
        serial.step(1e-3, cmd, nthreads)
    assert shared.t == serial.t
    for name in ("p", "v", "q", "w", "rotor_speeds"):
        assert getattr(shared, name).tobytes() == getattr(serial, name).tobytes(), name


def test_a_step_that_overflows_raises_instead_of_returning_nan(crazyflie):
    b = cufund.QuadrotorBatch(crazyflie, 2)
    b.hover(np.array([0.0, 0.0, 1.0]))
    b.torque_ext_B[1] = (1e300, 0.0, 0.0)  # finite, but the body rate overflows within the step
    with pytest.raises(ValueError, match=r"the step diverged: state \w+ of vehicle 1 is NaN or inf"):
        b.step(1e-3, np.full((2, 4), crazyflie.hover_rotor_speed))
    assert np.isfinite(b.w[0]).all()
    with pytest.raises(ValueError, match=r"state \w+ of vehicle 1 must be finite before a step"):
        b.step(1e-3, np.full((2, 4), crazyflie.hover_rotor_speed))  # and it stays an error, never silent
