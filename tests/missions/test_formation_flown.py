"""Leader–follower formation flown in flight (cufund.missions.formation_follower / formation_link).

- ``fleet_formation``: three vehicles in a wedge; each follower's formation error, recomputed here by hand from the
  vehicles' own 1 kHz truth records (not from the link's samples), is small and equals the metric; no collision.
- The follower hears only the leader's estimator: every message on its leader topic is one of the leader's
  ``/estimator/odometry`` messages (the same objects, published there first), and the link's bus view reads
  nothing else.
- Latency: on a straight leg at v a follower without prediction lags its slot by v times the message's age; the
  age grows by exactly the added latency, so the lag grows by v * latency (a hand estimate, checked to 10 %).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from cufund.core.config import ConfigError
from cufund.core.messages import Topics
from cufund.missions.formation_follower import LEADER_ODOMETRY, FormationFollowerParams, slot_setpoint
from cufund.missions.formation_link import formation_errors
from cufund.scenarios import load_scenario
from cufund.scenarios.fleet import build_fleet
from cufund.scenarios.schema import ScenarioConfig


@pytest.fixture(scope="module")
def formation_run():
    fleet = build_fleet(load_scenario("fleet_formation"))
    return fleet, fleet.run()


def _truth(run, name):
    s = run.runs[name].result.states
    return s["t"], s["p_W"], s["q_WB"]


def test_the_wedge_keeps_its_slots_against_the_truth(formation_run):
    fleet, run = formation_run
    assert run.status == "completed", run.message
    assert run.metrics["fleet_collisions"] == 0
    assert run.metrics["fleet_min_separation_m"] > 2.0
    t_L, p_L, q_L = _truth(run, "uav1")
    for name in ("uav2", "uav3"):
        offset = np.asarray(fleet.vehicle(name).config.planner.params.offset)
        t_F, p_F, _ = _truth(run, name)
        n = min(len(t_L), len(t_F))
        np.testing.assert_allclose(t_L[:n], t_F[:n])
        flying = p_L[:n, 2] > 0.5
        assert flying.sum() > 30_000  # > 30 s of the formation's flight at 1 kHz
        # by hand: the slot is the leader's true position plus the offset turned by the leader's true yaw
        w, x, y, z = q_L[:n][flying].T
        psi = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        slot = p_L[:n][flying] + np.stack(
            [np.cos(psi) * offset[0] - np.sin(psi) * offset[1], np.sin(psi) * offset[0] + np.cos(psi) * offset[1],
             np.full_like(psi, offset[2])], 1)  # fmt: skip
        d = np.linalg.norm(p_F[:n][flying] - slot, axis=1)
        rmse = math.sqrt(float(np.mean(d * d)))
        m = run.metrics["vehicles"][name]
        assert rmse < 0.15 and d.max() < 0.3, (name, rmse, d.max())  # a 2.5 m wedge held to a few cm
        assert m["formation_error_rmse_m"] == pytest.approx(rmse, rel=0.05)  # the metric's 250 Hz samples agree
        assert m["formation_error_max_m"] == pytest.approx(d.max(), rel=0.1)
        assert m["formation_messages_sent"] > 0.9 * 20 * run.metrics["sim_time_s"]
        # the follower landed in its slot next to where the leader landed
        assert np.linalg.norm(p_F[-1] - slot[-1] * [1, 1, 0]) < 0.3


def test_formation_errors_by_hand():
    """The metric's geometry on a leader heading north (yaw 90 degrees): the slot [-2, 1, 0] FLU is at (-1, -2)
    from the leader in ENU; a follower 0.5 m north of it is 0.5 m ahead, one 0.5 m east of it 0.5 m right."""
    q = np.array([[math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)]] * 2)
    p_L = np.array([[10.0, 5.0, 2.0]] * 2)
    p_F = np.array([[9.0, 3.5, 2.0], [9.5, 3.0, 2.0]])
    e, along, cross = formation_errors(p_L, q, p_F, np.array([-2.0, 1.0, 0.0]))
    np.testing.assert_allclose(e, [[0, 0.5, 0], [0.5, 0, 0]], atol=1e-12)
    np.testing.assert_allclose(along, [0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(cross, [0.0, -0.5], atol=1e-12)


def _column(latency: float, extrapolate: bool = False, **follower) -> ScenarioConfig:
    """A leader flying 24 m east at 2 m/s and one follower 3 m behind it."""
    data = load_scenario("fleet_formation").to_dict()
    data["trajectory"] = {"waypoints": [[0, 0, 2], [24, 0, 2]], "v_max": 2.0, "a_max": 1.5, "hover_s": 1.0}
    planner = {"kind": "formation_follower", "leader": "uav1", "offset": [-3, 0, 0], "comm_rate_hz": 50,
               "comm_latency_s": latency, "extrapolate": extrapolate, **follower}  # fmt: skip
    data["vehicles"] = [
        {"name": "uav1", "start": {"p": [0, 0, 0]}},
        {"name": "uav2", "start": {"p": [-3, 0, 0]}, "planner": planner},
    ]
    data["duration"] = 40.0
    return ScenarioConfig.from_dict(data)


# The latency tests' three followers of one leader, flown in one fleet: (comm_latency_s, extrapolate, lateral
# offset [m]). Each is 3 m behind the leader and 4 m from the others, so their along-track lags are those of three
# separate columns (uav2's to the bit; the others' differ by their own sensor draws).
COLUMN_FOLLOWERS = {"uav2": (0.0, False, 0.0), "uav3": (0.3, False, 4.0), "uav4": (0.3, True, -4.0)}


def _columns() -> ScenarioConfig:
    """:func:`_column`'s leader and its followers as COLUMN_FOLLOWERS says."""
    data = _column(0.0).to_dict()
    planner = data["vehicles"][1]["planner"]
    data["vehicles"] = [data["vehicles"][0]] + [
        {"name": name, "start": {"p": [-3, y, 0]},
         "planner": {**planner, "offset": [-3, y, 0], "comm_latency_s": latency, "extrapolate": extrapolate}}
        for name, (latency, extrapolate, y) in COLUMN_FOLLOWERS.items()
    ]  # fmt: skip
    return ScenarioConfig.from_dict(data)


@pytest.fixture(scope="module")
def cruise_lags() -> dict[str, tuple[float, float]]:
    """Each follower's mean along-track error [m] while the leader cruises (true speed within 2 % of 2 m/s), and
    the leader's mean speed then [m/s]."""
    fleet = build_fleet(_columns())
    run = fleet.run()
    assert run.status == "completed", run.message
    lags = {}
    for name, (_, _, y) in COLUMN_FOLLOWERS.items():
        s = fleet.formation_links[name].samples()
        v = np.gradient(s["p_L"][:, 0], s["t"])
        cruise = (np.abs(v - 2.0) < 0.04) & (s["p_L"][:, 2] > 1.9)
        assert cruise.sum() > 500  # > 2 s at 250 Hz
        offset = np.array([-3.0, y, 0])
        _, along, _ = formation_errors(s["p_L"][cruise], s["q_L"][cruise], s["p_F"][cruise], offset)
        lags[name] = (float(along.mean()), float(v[cruise].mean()))
    return lags


def test_latency_makes_the_follower_lag_by_speed_times_latency(cruise_lags):
    lag0, v = cruise_lags["uav2"]
    lag3, _ = cruise_lags["uav3"]
    # hand estimate: the message's age grows by the latency, so the lag by v * 0.3 s = 0.6 m
    assert lag3 - lag0 == pytest.approx(-v * 0.3, rel=0.1), (lag0, lag3)
    # without latency the lag is about v times half the 50 Hz broadcast period (0.02 m) plus the tracking lag
    assert -0.1 < lag0 < 0.0, lag0


def test_prediction_takes_the_latency_out(cruise_lags):
    lag0, _ = cruise_lags["uav2"]
    lag, _ = cruise_lags["uav4"]
    assert abs(lag - lag0) < 0.06, (lag0, lag)  # constant velocity: the prediction is exact up to tracking


def test_the_follower_hears_only_the_leaders_estimator():
    fleet = build_fleet(_column(0.1))
    fleet.advance_to(0.0)  # starts the run: the buses exist
    leader_bus, follower_bus = fleet.vehicle("uav1").bus, fleet.vehicle("uav2").bus
    sent = leader_bus.subscribe(Topics.ESTIMATE)
    heard = follower_bus.subscribe(LEADER_ODOMETRY)
    fleet.advance_to(6.0)
    estimates = {id(m): m for m in sent.take()}
    received = heard.take_stamped()
    assert len(received) > 200  # 50 Hz for ~6 s
    assert all(id(m) in estimates for _, m in received)  # each one the leader's estimator published
    # ... and each visible 0.1 s after it was sent, so at least 0.1 s after the estimate's own stamp
    assert all(t_vis - m.t >= 0.1 - 1e-9 for t_vis, m in received)
    link = fleet.formation_links["uav2"]
    assert link.view.reads == {str(Topics.ESTIMATE)}
    follower = next(c for c in fleet.vehicle("uav2").simulator.components if type(c).__name__ == "FormationFollower")
    reads = fleet.vehicle("uav2").simulator.views[follower.name].reads
    assert not any(str(r).startswith("/truth/") for r in reads), reads
    assert str(LEADER_ODOMETRY) in reads


def test_slot_velocity_includes_the_leaders_turn():
    """A leader at the origin yawing at 1 rad/s, heading east: the slot 2 m behind moves at 2 m/s to the south
    (omega x r with r = (-2, 0, 0))."""
    from cufund.core.messages import Odometry

    leader = Odometry(0.0, np.zeros(3), np.zeros(3), np.array([1.0, 0, 0, 0]), np.array([0, 0, 1.0]))
    p, v, yaw, rate = slot_setpoint(leader, np.array([-2.0, 0, 0]), 0.0)
    np.testing.assert_allclose(p, [-2, 0, 0])
    np.testing.assert_allclose(v, [0, -2, 0], atol=1e-12)
    assert yaw == 0 and rate == pytest.approx(1.0)


@pytest.mark.parametrize(
    ("change", "match"),
    [
        ({"leader": 3}, "planner.leader"),
        ({"offset": [1, 2]}, "planner.offset"),
        ({"comm_latency_s": -0.1}, "comm_latency_s"),
        ({"comm_rate_hz": 0}, "comm_rate_hz"),
        ({"extrapolate": "yes"}, "extrapolate"),
    ],
)
def test_bad_follower_params_are_refused_naming_the_field(change, match):
    kw = {"leader": "uav1", **change}
    with pytest.raises(ConfigError, match=match):
        FormationFollowerParams(**kw)


def test_a_leader_without_an_estimator_or_unknown_is_refused():
    data = _column(0.0).to_dict()
    data["vehicles"][1]["planner"]["leader"] = "uav9"
    with pytest.raises(ConfigError, match="uav9"):
        build_fleet(ScenarioConfig.from_dict(data))
    data["vehicles"][1]["planner"]["leader"] = ""  # none named: refused when built (the params build bare)
    with pytest.raises(ConfigError, match="planner.leader must name the leader"):
        build_fleet(ScenarioConfig.from_dict(data))
    data = _column(0.0).to_dict()
    data["vehicles"][0]["estimator"] = None
    with pytest.raises(ConfigError, match="leader 'uav1' has no estimator"):  # not the follower's own check
        build_fleet(ScenarioConfig.from_dict(data))


def test_a_live_fleet_keeps_only_the_links_newest_instants():
    """A live fleet may fly for hours: its links keep about the newest instants (as its vehicles' records), a run's
    keep all (its metrics need them)."""
    from cufund.apps.mavlink.fleet_live import LiveFleet

    fleet = build_fleet(_column(0.0))
    link = fleet.formation_links["uav2"]
    assert link.keep_rows is None
    link.keep_rows = 100
    fleet.advance_to(3.0)
    t = link.samples()["t"]
    assert 100 <= len(t) <= 200 and t[-1] == pytest.approx(3.0, abs=0.004)
    np.testing.assert_allclose(np.diff(t), 0.004, atol=1e-9)  # the newest ones, whole instants, in order
    live = LiveFleet(_column(0.0), start=False)
    assert live.fleet.formation_links["uav2"].keep_rows == 300_000  # 20 minutes at 250 Hz
