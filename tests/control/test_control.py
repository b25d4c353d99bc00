"""Flight control: hover, step responses in each mode, bumpless mode switches, saturation, large attitude errors."""

import math

import numpy as np
import pytest

import cufund
from cufund import FlightMode, RunStatus, Simulator, Topics
from cufund.control import AttitudeController, ControlAllocator, GeometricController, PositionController, RateController
from cufund.core.messages import AttitudeSetpoint, FlightModeCommand, TrajectorySetpoint
from cufund.geometry import quat_from_matrix, quat_to_matrix
from cufund.scenarios import load_scenario

PARAMS = cufund.vehicle.presets.cu_astro()
GAINS = load_scenario("square").controller.params
Z3 = np.zeros(3)


class Script(cufund.Component):
    """Publishes (start, topic, message-factory[, end]) events at 250 Hz from start until end (mode commands
    once, at their time)."""

    rate_hz = 250.0

    def __init__(self, events):
        self.events = sorted(events, key=lambda e: e[0])
        self.outputs = tuple({ev[1] for ev in self.events})

    def step(self, t, bus):
        for ev in self.events:
            t_ev, topic, make = ev[:3]
            t_end = ev[3] if len(ev) > 3 else math.inf
            if topic == Topics.FLIGHT_MODE:
                if abs(t - t_ev) < 1e-9:
                    bus.publish(topic, make(t))
            elif t_ev - 1e-9 <= t < t_end - 1e-9:
                bus.publish(topic, make(t))


def traj_sp(p=Z3, v=Z3, a=Z3, yaw=0.0):
    return lambda t: TrajectorySetpoint(
        t, np.asarray(p, float), np.asarray(v, float), np.asarray(a, float), Z3, yaw, 0.0
    )


def att_sp(roll=0.0, pitch=0.0, thrust=float("nan")):
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    R = np.array([[cp, sr * sp, cr * sp], [0, cr, -sr], [-sp, sr * cp, cr * cp]])  # R_y(pitch) R_x(roll)
    q = quat_from_matrix(R)
    return lambda t: AttitudeSetpoint(t, q, thrust)


def mode(m):
    return lambda t: FlightModeCommand(t, m)


def make_sim(kind, events=(), start=(0, 0, 5.0), initial_mode=FlightMode.POSITION):
    quad = cufund.Quadrotor(PARAMS)
    quad.hover(list(start))
    sim = Simulator(quad, record_topics=(Topics.ATTITUDE_SETPOINT, Topics.ACTUATOR_COMMAND))
    sim.add(Script(list(events)))
    if kind == "pid":
        sim.add(PositionController(PARAMS, GAINS.position, mode=initial_mode))
        sim.add(AttitudeController(GAINS.attitude))
        sim.add(RateController(PARAMS, GAINS.rate))
    else:
        sim.add(GeometricController(PARAMS, GAINS.geometric, mode=initial_mode))
    return sim


def tilt_deg(q):
    q = np.atleast_2d(q)
    return np.degrees(np.arccos(np.clip(1 - 2 * (q[:, 1] ** 2 + q[:, 2] ** 2), -1, 1)))


KINDS = ["pid", "geometric"]


@pytest.mark.parametrize("kind", KINDS)
def test_hover_holds_position(kind):
    r = make_sim(kind).run(3.0)
    assert r.status is RunStatus.COMPLETED
    assert np.abs(r.states["p_W"] - [0, 0, 5]).max() < 1e-4
    hover = PARAMS.hover_rotor_speed
    np.testing.assert_allclose(r.states["rotor_speeds"][-1], hover, rtol=1e-3)


@pytest.mark.parametrize("kind", KINDS)
def test_position_step(kind):
    r = make_sim(kind, [(0.0, Topics.TRAJECTORY_SETPOINT, traj_sp(p=[1, 0, 5]))]).run(4.0)
    x, t = r.states["p_W"][:, 0], r.states["t"]
    assert x.max() < 1.25  # overshoot under 25 %
    assert abs(x[t >= 3.0] - 1).max() < 0.03  # settled
    assert np.abs(r.states["p_W"][:, 2] - 5).max() < 0.1


@pytest.mark.parametrize("kind", KINDS)
def test_velocity_step(kind):
    r = make_sim(
        kind,
        [
            (0.0, Topics.FLIGHT_MODE, mode(FlightMode.VELOCITY)),
            (0.0, Topics.TRAJECTORY_SETPOINT, traj_sp(v=[1.0, -0.5, 0.2])),
        ],
    ).run(5.0)
    v, t = r.states["v_W"], r.states["t"]
    late = t >= 4.0
    np.testing.assert_allclose(v[late], np.tile([1.0, -0.5, 0.2], (np.count_nonzero(late), 1)), atol=0.03)


@pytest.mark.parametrize("kind", KINDS)
def test_attitude_step(kind):
    roll = math.radians(15)
    thrust = PARAMS.mass * PARAMS.gravity / math.cos(roll)
    r = make_sim(
        kind,
        [
            (0.0, Topics.FLIGHT_MODE, mode(FlightMode.ATTITUDE)),
            (0.0, Topics.MANUAL_ATTITUDE_SETPOINT, att_sp(roll=roll, thrust=thrust)),
        ],
    ).run(1.5)
    t, q = r.states["t"], r.states["q_WB"]
    assert np.abs(tilt_deg(q[t >= 0.8]) - 15).max() < 1.0
    # thrust tilted to +roll (body y to world z) accelerates towards -y, holding height
    assert r.states["v_W"][-1, 1] < -1.5 and abs(r.states["v_W"][-1, 2]) < 0.3


def _jumps(r, t_switch, window=0.1):
    """Largest change between consecutive attitude setpoints (angle [deg], thrust [N]) near t_switch."""
    a = r.topics[Topics.ATTITUDE_SETPOINT]
    m = np.abs(a["t"] - t_switch) < window
    q, f = a["q_WB"][m], a["thrust"][m]
    dq = np.abs(np.sum(q[1:] * q[:-1], axis=1))
    return np.degrees(2 * np.arccos(np.clip(dq, 0, 1))).max(), np.abs(np.diff(f)).max()


@pytest.mark.parametrize("kind", KINDS)
def test_mode_switches_without_jump(kind):
    """Flying at 1 m/s in velocity mode, then attitude mode (holding the last attitude), then position mode
    (holding where it is): the commanded attitude and thrust stay continuous and the vehicle does not lurch."""
    events = [
        (0.0, Topics.FLIGHT_MODE, mode(FlightMode.VELOCITY)),
        (0.0, Topics.TRAJECTORY_SETPOINT, traj_sp(v=[1.0, 0, 0]), 2.0),
        (2.0, Topics.FLIGHT_MODE, mode(FlightMode.ATTITUDE)),
        (2.5, Topics.FLIGHT_MODE, mode(FlightMode.POSITION)),
    ]
    r = make_sim(kind, events).run(4.5)
    assert r.status is RunStatus.COMPLETED
    for ts in (2.0, 2.5):
        dang, dthrust = _jumps(r, ts)
        assert dang < 1.0 and dthrust < 0.3, (ts, dang, dthrust)
    t, p, v = r.states["t"], r.states["p_W"], r.states["v_W"]
    # position mode brakes from ~1 m/s along a critically damped reference (stops 2 tau v0 = 0.5 m on) and holds
    i = np.searchsorted(t, 2.5)
    stop = p[i] + 0.5 * v[i]
    assert np.linalg.norm(p[-1] - stop) < 0.05 and np.linalg.norm(v[-1]) < 0.05
    # velocity mode does not hold altitude (the initial step costs some); from the first switch on, it stays
    z_switch = p[np.searchsorted(t, 2.0), 2]
    assert np.abs(p[t >= 2.0, 2] - z_switch).max() < 0.05


def test_allocator_keeps_roll_pitch_under_saturation():
    alloc = ControlAllocator(PARAMS)
    hover = PARAMS.mass * PARAMS.gravity
    A = PARAMS.allocation_matrix()
    # roll torque plus a yaw torque far beyond what fits: roll is delivered exactly, yaw reduced
    w = alloc.rotor_speeds(hover, np.array([0.3, 0.0, 0.5]))
    achieved = A @ (PARAMS.k_f * w**2)
    assert achieved[1] == pytest.approx(0.3, rel=1e-9)
    assert 0 < achieved[3] < 0.5 and alloc.last_saturation.torque == (0, 0, 1)
    # at full collective thrust, roll still comes through by lowering the collective
    w = alloc.rotor_speeds(alloc.max_thrust, np.array([0.2, -0.1, 0.0]))
    achieved = A @ (PARAMS.k_f * w**2)
    np.testing.assert_allclose(achieved[1:3], [0.2, -0.1], rtol=1e-9)
    assert achieved[0] < alloc.max_thrust and alloc.last_saturation.thrust == 1
    assert np.all(w <= PARAMS.rotor_speed_max + 1e-9) and np.all(w >= 0)


@pytest.mark.parametrize("kind", KINDS)
def test_recovers_from_motor_saturation(kind):
    """A 15 rad/s roll spin saturates the motors; the vehicle still levels off and holds its position."""
    sim = make_sim(kind, start=(0, 0, 10.0))
    sim.vehicle.state.w[:] = (15.0, -5.0, 2.0)
    r = sim.run(4.0)
    sat = r.topics[Topics.ACTUATOR_COMMAND]["rotor_speeds"]
    assert np.any(np.isclose(sat, PARAMS.rotor_speed_max) | np.isclose(sat, 0.0))
    t = r.states["t"]
    assert r.status is RunStatus.COMPLETED
    assert tilt_deg(r.states["q_WB"][t >= 3.0]).max() < 2.0
    assert np.linalg.norm(r.states["p_W"][-1] - [0, 0, 10]) < 0.3


def test_geometric_recovers_from_150_deg_tilt():
    sim = make_sim("geometric", start=(0, 0, 20.0))
    a = math.radians(150)
    sim.vehicle.state.q[:] = (math.cos(a / 2), 0.8 * math.sin(a / 2), 0.6 * math.sin(a / 2), 0.0)
    r = sim.run(5.0)
    t = r.states["t"]
    assert tilt_deg(r.states["q_WB"][0])[0] == pytest.approx(150, abs=1e-6)
    assert tilt_deg(r.states["q_WB"][t >= 3.0]).max() < 1.0
    assert np.linalg.norm(r.states["p_W"][-1] - [0, 0, 20]) < 0.05
    assert r.states["p_W"][:, 2].min() > 15.0


def test_rotation_helpers_round_trip():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(0)
    for _ in range(50):
        q = rng.standard_normal(4)
        q /= np.linalg.norm(q)
        q = q if q[0] >= 0 else -q
        R = Rotation.from_quat(q[[1, 2, 3, 0]]).as_matrix()  # scipy: [x, y, z, w], independent of ours
        np.testing.assert_allclose(quat_to_matrix(q), R, atol=1e-12)
        np.testing.assert_allclose(quat_from_matrix(R), q, atol=1e-12)
        np.testing.assert_allclose(quat_from_matrix(quat_to_matrix(q)), q, atol=1e-12)


@pytest.mark.parametrize("kind", KINDS)
def test_switch_out_of_a_tilted_attitude_is_smooth(kind):
    """Attitude mode at 10 deg roll, then velocity mode: the commanded attitude fades from the tilt to what the
    velocity loop wants instead of snapping back level."""
    roll = math.radians(10)
    thrust = PARAMS.mass * PARAMS.gravity / math.cos(roll)
    events = [
        (0.0, Topics.FLIGHT_MODE, mode(FlightMode.ATTITUDE)),
        (0.0, Topics.MANUAL_ATTITUDE_SETPOINT, att_sp(roll=roll, thrust=thrust), 1.0),
        (1.0, Topics.FLIGHT_MODE, mode(FlightMode.VELOCITY)),
    ]
    r = make_sim(kind, events).run(2.5)
    dang, dthrust = _jumps(r, 1.0)
    assert dang < 1.0 and dthrust < 0.3, (dang, dthrust)
    # and the velocity loop then holds the velocity the vehicle had at the switch
    t, v = r.states["t"], r.states["v_W"]
    np.testing.assert_allclose(v[-1], v[np.searchsorted(t, 1.0)], atol=0.05)
