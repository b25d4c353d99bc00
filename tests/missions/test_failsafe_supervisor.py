"""The failsafe supervisor's decisions, each trigger driven through a bus by a test publisher: when each failsafe
fires, what it asks of the reference owner, the events (name, reason, severity) and the escalation rules."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from cufund.core.config import ConfigError
from cufund.core.messages import BatteryStatus, GpsFix, Odometry, OdometryDiagnostics, Topics
from cufund.missions.failsafe_params import FailsafeParams, parse_failsafe
from cufund.missions.failsafe_supervisor import FailsafeSupervisor
from cufund.scenarios import load_scenario


class _Sub:
    def __init__(self) -> None:
        self.items: list[Any] = []

    def take(self) -> list[Any]:
        out, self.items = self.items, []
        return out


class _Bus:
    """What the supervisor uses of a BusView: latest, subscribe, publish."""

    def __init__(self) -> None:
        self._latest: dict[str, Any] = {}
        self._subs: dict[str, list[_Sub]] = {}
        self.published: list[tuple[str, Any]] = []

    def latest(self, topic: str) -> Any:
        return self._latest.get(str(topic))

    def subscribe(self, topic: str) -> _Sub:
        s = _Sub()
        self._subs.setdefault(str(topic), []).append(s)
        return s

    def publish(self, topic: str, msg: Any) -> None:
        self._latest[str(topic)] = msg
        for s in self._subs.get(str(topic), []):
            s.items.append(msg)
        self.published.append((str(topic), msg))


class _Owner:
    """A reference owner that records what it is asked."""

    def __init__(self) -> None:
        self.asked: list[tuple[float, str]] = []
        self.home_W = None

    def landing(self, t: float) -> bool:
        return any(a in ("land", "rtl") for _, a in self.asked)

    def hold(self, t, reason, bus, temporary=False):
        self.asked.append((t, "hold"))
        return ""

    def land(self, t, reason, bus, urgent=False):
        self.asked.append((t, "land"))
        return ""

    def rtl(self, t, reason, bus):
        self.asked.append((t, "rtl"))
        return ""

    def disarm(self, t, reason, bus):
        self.asked.append((t, "disarm"))
        return ""


def _state(t: float, p=(0.0, 0.0, 1.5)) -> Odometry:
    return Odometry(t, np.array(p, float), np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]), np.zeros(3))


def _fly(sup: FailsafeSupervisor, until: float, each=None, p=lambda t: (0.0, 0.0, 1.5)) -> _Bus:
    """Runs the supervisor at its rate from 0 to ``until`` with the vehicle airborne at ``p(t)``; ``each(t, bus)``
    publishes the test's trigger first."""
    bus = _Bus()
    sup.reset()
    sup.setup(bus)
    home = _state(0.0, (0.0, 0.0, 0.0))
    bus.publish(Topics.TRUTH_ODOMETRY, home)
    sup.step(0.0, bus)  # home on the ground
    for k in range(1, int(round(until * sup.rate_hz)) + 1):
        t = k / sup.rate_hz
        if each is not None:
            each(t, bus)
        bus.publish(Topics.TRUTH_ODOMETRY, _state(t, p(t)))
        sup.step(t, bus)
    return bus


def _diag(t: float, healthy: bool) -> OdometryDiagnostics:
    return OdometryDiagnostics(
        t, 100, 90, 3, np.ones(6), np.zeros((0, 6)), 1.0, 1.0, "", healthy, "" if healthy else "degenerate"
    )


def test_estimator_unhealthy_holds_after_the_delay_then_lands():
    owner = _Owner()
    sup = FailsafeSupervisor(FailsafeParams(), owner, estimator_diagnostics=True)

    def lio(t, bus):  # a LiDAR frame every 0.1 s, unhealthy from t = 2 s on
        if abs(t * 10 - round(t * 10)) < 1e-9:
            bus.publish(Topics.ESTIMATOR_DIAGNOSTICS, _diag(t, t < 2.0))

    _fly(sup, 10.0, lio)
    assert [a for _, a in owner.asked] == ["hold", "land"]
    (t_hold, _), (t_land, _) = owner.asked
    assert t_hold == pytest.approx(2.0 + 1.0)  # COM_POS_FS_DELAY
    assert t_land == pytest.approx(t_hold + 5.0)  # COM_FAIL_ACT_T
    assert [r[1] for r in sup.records] == ["hold", "land"]
    assert "hold" in sup.records[0][2] and "degenerate" in sup.records[0][2]
    events = sup.events.of_kind("failsafe")
    assert [e["action"] for e in events] == ["hold", "land"]
    assert [e["severity"] for e in events] == ["warning", "critical"]
    assert sup.ended_flight == "failsafe_landed"


def test_estimator_silence_counts_and_recovery_cancels_the_landing():
    owner = _Owner()
    sup = FailsafeSupervisor(FailsafeParams(), owner, estimator_diagnostics=True)

    def lio(t, bus):  # frames until 2 s, none from 2 to 4 s, then frames again
        if abs(t * 10 - round(t * 10)) < 1e-9 and not 2.0 <= t < 4.0:
            bus.publish(Topics.ESTIMATOR_DIAGNOSTICS, _diag(t, True))

    _fly(sup, 10.0, lio)
    assert [a for _, a in owner.asked] == ["hold"]
    assert owner.asked[0][0] == pytest.approx(1.9 + 0.35 + 0.05 + 1.0, abs=0.051)  # silence seen, then the delay
    assert "no LiDAR frame" in sup.records[0][2]
    assert "healthy again" in sup.records[-1][2]
    assert sup.ended_flight is None  # it held and nobody landed: the operator's turn


class _PathKeeper(_Owner):
    """A follower's takeover: the estimator's temporary hold keeps the planned path (nothing to give back)."""

    def hold(self, t, reason, bus, temporary=False):
        super().hold(t, reason, bus, temporary)
        return "the planned path is kept" if temporary else ""


def test_each_estimator_spell_of_an_owner_that_kept_its_path_is_one_hold_then_cleared():
    owner = _PathKeeper()
    sup = FailsafeSupervisor(FailsafeParams(), owner, estimator_diagnostics=True)

    def lio(t, bus):  # unhealthy from 2 to 4 s and from 6 to 8 s (each recovers within COM_FAIL_ACT_T)
        if abs(t * 10 - round(t * 10)) < 1e-9:
            bus.publish(Topics.ESTIMATOR_DIAGNOSTICS, _diag(t, not (2.0 <= t < 4.0 or 6.0 <= t < 8.0)))

    _fly(sup, 12.0, lio)
    kinds = [
        ("hold" if "failsafe hold" in r[2] else "cleared" if "healthy again" in r[2] else r[2]) for r in sup.records
    ]
    assert kinds == ["hold", "cleared", "hold", "cleared"]
    assert [a for _, a in owner.asked] == ["hold", "hold"]
    assert sup.action == "none" and sup.ended_flight is None


def test_an_estimator_spell_during_a_geofence_hold_neither_clears_nor_lifts_it():
    owner = _Owner()
    sup = FailsafeSupervisor(FailsafeParams(GF_MAX_HOR_DIST=1.0), owner, estimator_diagnostics=True)

    def lio(t, bus):  # unhealthy from 4 to 6 s, after the geofence hold at 2 s
        if abs(t * 10 - round(t * 10)) < 1e-9:
            bus.publish(Topics.ESTIMATOR_DIAGNOSTICS, _diag(t, not 4.0 <= t < 6.0))

    _fly(sup, 9.0, lio, p=lambda t: (min(t, 2.0) * 0.6, 0.0, 1.5))
    assert [a for _, a in owner.asked] == ["hold"]
    assert not any("healthy again" in r[2] for r in sup.records)  # there was no estimator hold to clear
    assert sup.action == "hold"


def test_short_unhealthy_spells_fire_nothing():
    owner = _Owner()
    sup = FailsafeSupervisor(FailsafeParams(), owner, estimator_diagnostics=True)

    def lio(t, bus):
        if abs(t * 10 - round(t * 10)) < 1e-9:
            bus.publish(Topics.ESTIMATOR_DIAGNOSTICS, _diag(t, not (2.0 <= t < 2.8)))

    _fly(sup, 6.0, lio)
    assert owner.asked == [] and sup.records == []
    assert sup.health.events and sup.health.events[0][1] == pytest.approx(0.8)  # the spell is recorded


def _gps(t: float) -> GpsFix:
    return GpsFix(t, 47.0, 8.0, 400.0, np.zeros(3), 3, 12, 0.5, 0.8)


@pytest.mark.parametrize("gps_only", [True, False])
def test_gps_loss_fails_safe_only_under_a_gps_only_estimate(gps_only):
    owner = _Owner()
    sup = FailsafeSupervisor(FailsafeParams(), owner, gps_topic=str(Topics.GPS), gps_only=gps_only)

    def gps(t, bus):  # 10 Hz fixes until 3 s
        if t < 3.0 and abs(t * 10 - round(t * 10)) < 1e-9:
            bus.publish(Topics.GPS, _gps(t))

    _fly(sup, 11.0, gps)
    if gps_only:
        assert [a for _, a in owner.asked] == ["hold", "land"]
        assert owner.asked[0][0] == pytest.approx(2.9 + 0.5 + 1.0, abs=0.051)  # GPS_LOSS_T, COM_POS_FS_DELAY
        assert "GPS lost" in sup.records[0][2]
    else:
        assert owner.asked == [] and sup.records == []
        assert any("GPS lost" in e["message"] for e in sup.events.of_kind("info"))


def _battery(remaining: float):
    def publish(t, bus):
        r = remaining(t)
        bus.publish(Topics.BATTERY, BatteryStatus(t, 14.0 + r, 10.0, r, 1000.0 * (1 - r), 4))

    return publish


@pytest.mark.parametrize(
    "act, expected",
    [(0, []), (1, ["rtl", "land"]), (2, ["land"]), (3, ["rtl", "land"])],
)
def test_battery_actions_per_com_low_bat_act(act, expected):
    owner = _Owner()
    owner.landing = lambda t: False  # keep asking: the escalation is what is tested
    sup = FailsafeSupervisor(FailsafeParams(COM_LOW_BAT_ACT=act), owner)
    bus = _fly(sup, 10.0, _battery(lambda t: 0.30 - 0.03 * t))  # low at 5 s, critical at 7.67, emergency at 8.33
    assert [a for _, a in owner.asked] == expected
    times = {1: [5.0, 7.7], 2: [7.7], 3: [7.7, 8.35]}.get(act, [])
    assert [t for t, _ in owner.asked] == pytest.approx(times, abs=0.026)
    assert all("battery" in r[2] for r in sup.records)
    assert len(sup.records) == 3  # low, critical, emergency: each announced once (warnings too)
    assert all(t != str(Topics.VEHICLE_STATUS) for t, _ in bus.published)  # it publishes a disarm only


def test_battery_never_downgrades_a_landing():
    owner = _Owner()
    owner.landing = lambda t: False
    sup = FailsafeSupervisor(FailsafeParams(), owner)
    _fly(sup, 4.0, _battery(lambda t: 0.05 if t < 2 else 0.14))  # critical first, then a "low" reading
    assert [a for _, a in owner.asked] == ["land"]


@pytest.mark.parametrize(
    "action, asked", [(0, []), (1, []), (2, ["hold"]), (3, ["rtl"]), (4, ["disarm"]), (5, ["land"])]
)
def test_geofence_actions(action, asked):
    owner = _Owner()
    owner.landing = lambda t: False
    sup = FailsafeSupervisor(FailsafeParams(GF_ACTION=action, GF_MAX_HOR_DIST=2.0, GF_MAX_VER_DIST=3.0), owner)
    _fly(sup, 4.0, p=lambda t: (t, 0.0, 1.5))  # flies away at 1 m/s: beyond 2 m after 2 s
    assert [a for _, a in owner.asked] == asked
    if asked:
        assert owner.asked[0][0] == pytest.approx(2.05)
        assert "GF_MAX_HOR_DIST" in sup.records[0][2]
    assert len(sup.records) == (0 if action == 0 else 1)


def test_geofence_vertical_and_nothing_on_the_ground():
    owner = _Owner()
    sup = FailsafeSupervisor(FailsafeParams(GF_MAX_VER_DIST=2.0), owner)
    _fly(sup, 4.0, p=lambda t: (0.0, 0.0, 1.0 + 0.5 * t))  # above 2 m after 2 s
    assert [a for _, a in owner.asked] == ["hold"] and "GF_MAX_VER_DIST" in sup.records[0][2]
    grounded = FailsafeSupervisor(FailsafeParams(), _Owner(), estimator_diagnostics=True)
    _fly(grounded, 6.0, lambda t, bus: None, p=lambda t: (0.0, 0.0, 0.0))  # silent LIO, but never airborne
    assert grounded.records == []


def test_a_flight_without_triggers_sees_no_failsafe():
    owner = _Owner()
    sup = FailsafeSupervisor(FailsafeParams(GF_MAX_HOR_DIST=5.0), owner, estimator_diagnostics=True)

    def healthy(t, bus):
        if abs(t * 10 - round(t * 10)) < 1e-9:
            bus.publish(Topics.ESTIMATOR_DIAGNOSTICS, _diag(t, True))
        _battery(lambda t: 0.9)(t, bus)

    _fly(sup, 10.0, healthy, p=lambda t: (np.cos(t), np.sin(t), 1.5))
    assert owner.asked == [] and sup.records == [] and sup.ended_flight is None


def test_params_errors_name_the_field_and_off_disables():
    with pytest.raises(ConfigError, match="failsafe.COM_LOW_BAT_ACT must be one of"):
        FailsafeParams(COM_LOW_BAT_ACT=7)
    with pytest.raises(ConfigError, match="failsafe.GF_MAX_HOR_DIST"):
        FailsafeParams(GF_MAX_HOR_DIST=-1.0)
    with pytest.raises(ConfigError, match="BAT_LOW_THR >= BAT_CRIT_THR"):
        FailsafeParams(BAT_LOW_THR=0.05, BAT_CRIT_THR=0.1)
    with pytest.raises(ConfigError, match="unknown key 'GF_MAX_DIST' in failsafe"):
        parse_failsafe({"GF_MAX_DIST": 3})
    with pytest.raises(ConfigError, match="failsafe must be a mapping"):
        parse_failsafe(3)
    assert parse_failsafe("off") is False and parse_failsafe(None) == FailsafeParams()
    c = load_scenario("square", ["failsafe=off"])
    assert c.failsafe is False and load_scenario("square", ["failsafe=off"]).to_dict()["failsafe"] is False
    c = load_scenario("square", ["failsafe.GF_MAX_HOR_DIST=3", "failsafe.GF_ACTION=3"])
    assert c.failsafe.GF_MAX_HOR_DIST == 3.0 and c.failsafe.GF_ACTION == 3
    assert c.with_overrides([]).failsafe == c.failsafe  # round trip through to_dict


def test_a_follower_taken_over_ignores_the_replanners_updates():
    from cufund.missions.failsafe_takeover import FollowerTakeover
    from cufund.planning.sequence import Hold
    from cufund.planning.trajectory_follower import TrajectoryFollower

    follower = TrajectoryFollower(Hold(np.array([0.0, 0.0, 1.5]), 100.0), rate_hz=50.0)
    takeover = FollowerTakeover(follower, FailsafeParams())
    takeover.home_W = np.zeros(3)
    follower.stitch(1.0, Hold(np.array([1.0, 0.0, 1.5]), 100.0, t_start=1.0))  # a replanner's update: flown
    assert np.allclose(follower.trajectory.sample(2.0).p_W[0], [1.0, 0.0, 1.5])
    note = takeover.hold(2.0, "estimator", None, temporary=True)  # the estimator's hold keeps the path
    assert "kept" in note and np.allclose(follower.trajectory.sample(3.0).p_W[0], [1.0, 0.0, 1.5])
    assert takeover.land(3.0, "battery", None) == ""
    follower.stitch(4.0, Hold(np.array([5.0, 0.0, 1.5]), 100.0, t_start=4.0))  # ignored from now on
    p_end = follower.trajectory.sample(60.0).p_W[0]
    assert np.allclose(p_end[:2], [1.0, 0.0]) and p_end[2] < 0.0  # landed where it was (the reference below ground)
    takeover.reset()  # a new run: the planner flies again
    follower.stitch(5.0, Hold(np.array([2.0, 0.0, 1.5]), 100.0, t_start=5.0))
    assert np.allclose(follower.trajectory.sample(6.0).p_W[0], [2.0, 0.0, 1.5])
