"""The tunnel mission's stepwise mode (``through: stepwise``, issue 26 item 4a: a forward camera sees the frames
one by one), driven with scripted TunnelEstimate messages on a bus: frames appear one at a time, the estimate
follows the reference exactly. Checked against the scripted course's geometry (passages through its openings,
planes of the frames not yet published), independently of the mission's own bookkeeping."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np
import pytest

from cufund import ConfigError
from cufund.core.bus import Bus, BusView
from cufund.core.messages import Odometry, Topics, TunnelEstimate
from cufund.missions.tunnel import TunnelMission, TunnelMissionParams
from cufund.missions.tunnel_geometry import frame_boxes, passages

PAD = np.array([-2.5, 0.0, 0.0])
YAWS = np.radians([0.0, 10.0, 20.0])
CENTRES = np.array([[0.0, 0.0, 1.0], [1.0, 0.2, 1.05], [2.1, 0.5, 1.0]])
NORMALS = np.stack([np.cos(YAWS), np.sin(YAWS), np.zeros(3)], axis=1)
SIZES = np.full((3, 2), 0.8)
DT = 0.05  # the mission's 20 Hz
EST_EVERY = 4  # an estimate every 0.2 s (the camera detector's 5 Hz)


def _estimate(t: float, shown: list[int]) -> TunnelEstimate:
    k = len(shown)
    return TunnelEstimate(
        t=t,
        centres_W=CENTRES[shown].reshape(k, 3),
        normals_W=NORMALS[shown].reshape(k, 3),
        opening_sizes=SIZES[shown].reshape(k, 2),
        confidence=np.full(k, 0.9),
        scans=1,
    )


def _fly(
    params: TunnelMissionParams,
    shown: Callable[[float, TunnelMission], list[int]],
    t_max: float = 150.0,
    on_step: Callable[[float, TunnelMission], None] | None = None,
    estimate: Callable[[float, list[int]], TunnelEstimate] = _estimate,
) -> tuple[TunnelMission, np.ndarray, np.ndarray, list[tuple[float, list[int]]]]:
    """Steps the mission at 20 Hz with a state estimate that is its own reference (perfect tracking) and an
    estimate (``estimate``) of the frames ``shown(t, mission)`` every 0.2 s. Returns the mission, the flown
    positions (N, 3) and yaws (N,) and the frames of the newest published estimate at each plan's time."""
    m = TunnelMission(params, PAD)
    m.active_state_topic = Topics.ESTIMATE
    bus = Bus()
    view = BusView(bus, m.name, m.inputs + m.optional_inputs, m.outputs, deny_truth=True)
    m.reset()
    m.setup(view)
    q = np.array([1.0, 0.0, 0.0, 0.0])
    flown, shown_at_plan = [], []
    published: list[int] = []
    for i in range(int(t_max / DT)):
        t = i * DT
        s = m.reference.sample(t)
        p = s.p_W[0]
        flown.append([*p, s.yaw[0]])
        bus.publish(Topics.ESTIMATE, Odometry(t, p.copy(), s.v_W[0].copy(), q, np.zeros(3)))
        now = shown(t, m)
        if i % EST_EVERY == 0:
            bus.publish(Topics.TUNNEL_ESTIMATE, estimate(t, now))
            published = list(now)
        n_plans = len(m.plans)
        m.step(t, view)
        shown_at_plan += [(t, published)] * (len(m.plans) - n_plans)
        if on_step is not None:
            on_step(t, m)
        if m.finished and m.t_end is not None and t > m.t_end + 1.0:
            break
    a = np.array(flown)
    return m, a[:, :3], a[:, 3], shown_at_plan


def _after_wait(seconds: float) -> Callable[[float, TunnelMission], list[int]]:
    """Frame 1 from the start; frame k+1 once the mission has waited ``seconds`` past frame k."""
    state: dict[str, float] = {}
    released = [0]

    def shown(t: float, m: TunnelMission) -> list[int]:
        if m.state == "wait":
            key = f"wait{m.transitions[-1][0]}"
            state.setdefault(key, t)
            if t - state[key] >= seconds and len(released) < 3 and len(released) <= m.progress:
                released.append(len(released))
        return list(released)

    return shown


STEPWISE = TunnelMissionParams(frames=3, through="stepwise", detect_timeout_s=6.0)


def test_stepwise_waits_for_each_frame_and_hops_through_them_in_order():
    m, flown, yaw, shown_at_plan = _fly(STEPWISE, _after_wait(2.0))
    assert m.state == "done", (m.state, m.reason)
    states = [s for _, s, _ in m.transitions]
    assert states == [
        "initialise", "takeoff", "detect", "align", "enter", "wait", "through", "wait", "through", "land", "done"
    ]  # fmt: skip
    # it waited (at rest) at least the 2 s before each next frame was shown
    waits = [(a, b) for (a, s, _), (b, _, _) in itertools.pairwise(m.transitions) if s == "wait"]
    assert len(waits) == 2 and all(b - a >= 2.0 for a, b in waits)
    for a, b in waits:
        i, j = int(round(a / DT)) + 2, int(round(b / DT))
        assert np.ptp(flown[i:j], axis=0).max() < 1e-6  # hovering still
    # every frame passed inside its opening, in order, never touching a bar; landed beyond the last one
    idx = passages(flown, CENTRES, NORMALS, SIZES)
    assert None not in idx and idx == sorted(idx), idx
    assert frame_boxes(CENTRES, NORMALS, SIZES, 0.05).distance(flown).min() > 0.17
    assert (flown[-1] - CENTRES[2]) @ NORMALS[2] > 0.9 and flown[-1][2] < 0.05
    assert m.progress == 3 and m.passed is not None and m.passed.centres.shape == (3, 3)
    # the heading turned to face along each frame it waited behind
    assert yaw[int(round(waits[1][0] / DT)) + 5] == pytest.approx(YAWS[1], abs=1e-6)
    assert yaw[int(round(waits[0][0] / DT)) + 5] == pytest.approx(YAWS[0], abs=1e-6)


def test_stepwise_never_plans_through_a_frame_not_yet_detected():
    m, _, _, shown_at_plan = _fly(STEPWISE, _after_wait(2.0))
    assert m.state == "done"
    hops = [(r, s) for r, (_, s) in zip(m.plans, shown_at_plan, strict=True) if r.leg in ("enter", "through")]
    assert [len(s) for _, s in hops] == [1, 2, 3]
    for r, s in hops:
        hidden = [k for k in range(3) if k not in s]
        p = r.trajectory.sample(np.arange(r.trajectory.t_knots[0], r.trajectory.t_end, 0.01)).p_W
        for k in hidden:  # never reaches the plane of a frame it has not been shown
            assert float(np.max((p - CENTRES[k]) @ NORMALS[k])) < -0.1, (r.leg, k)
        # each hop passes exactly one new frame (the nearest one shown beyond the last passed)
        assert sum(i is not None for i in passages(p, CENTRES, NORMALS, SIZES)) == 1


def test_stepwise_enters_with_only_the_first_frame_where_all_waits():
    """Only frame 1 is ever shown: stepwise enters and passes it, then times out waiting for frame 2 and lands
    where it rests past frame 1 (the descent clear of its bars); ``all`` (the default) never enters."""
    only_first = lambda t, m: [0]  # noqa: E731
    m, flown, _, _ = _fly(STEPWISE, only_first)
    assert m.state == "aborted"
    assert m.reason.startswith("frame 2 of 3 not detected, confident and stable in 6 s past frame 1"), m.reason
    states = [s for _, s, _ in m.transitions]
    assert states == ["initialise", "takeoff", "detect", "align", "enter", "wait", "aborted"]
    assert passages(flown, CENTRES[:1], NORMALS[:1], SIZES[:1]) != [None]  # it went through frame 1
    assert 0.2 < (flown[-1] - CENTRES[0]) @ NORMALS[0] < 0.5 and flown[-1][2] < 0.05  # landed past it
    assert np.max((flown - CENTRES[1]) @ NORMALS[1]) < -0.1  # never reached frame 2's plane
    assert frame_boxes(CENTRES, NORMALS, SIZES, 0.05).distance(flown).min() > 0.17
    assert [r.leg for r in m.plans] == ["align", "enter"]

    a, flown_a, _, _ = _fly(TunnelMissionParams(frames=3, detect_timeout_s=6.0), only_first)
    assert a.state == "aborted" and a.reason.startswith("detected 1 of 3 frames"), a.reason
    assert "enter" not in [s for _, s, _ in a.transitions]
    assert np.max((flown_a - CENTRES[0]) @ NORMALS[0]) < -0.4  # never nearer than the creep point


def test_stepwise_backs_out_when_the_descent_is_not_clear(monkeypatch):
    """Where landing in place would come within clearance of a bar (forced here), the abort backs out through
    the passed openings in reverse and lands before the course."""
    monkeypatch.setattr(TunnelMission, "_descent_clear", lambda self, p, d: False)
    m, flown, _, _ = _fly(STEPWISE, lambda t, m: [0, 1] if m.progress >= 1 or m.state != "wait" else [0])
    assert m.state == "aborted" and m.reason.startswith("frame 3 of 3 not detected"), m.reason
    i_wait = int(round(m.transitions[-2][0] / DT))
    assert passages(flown[i_wait:], CENTRES[:2][::-1], -NORMALS[:2][::-1], SIZES[:2]) != [None, None]
    idx = passages(flown[i_wait:], CENTRES[:2], -NORMALS[:2], SIZES[:2])
    assert idx[1] < idx[0]  # back through frame 2, then frame 1
    assert (flown[-1] - CENTRES[0]) @ NORMALS[0] < -0.5 and flown[-1][2] < 0.05  # landed before the course
    assert frame_boxes(CENTRES, NORMALS, SIZES, 0.05).distance(flown).min() > 0.17
    assert m.plans[-1].leg == "back_out" and m.plans[-1].ok


def test_default_mode_still_plans_through_every_frame_at_once():
    m, flown, yaw, _ = _fly(TunnelMissionParams(frames=3), lambda t, m: [0, 1, 2])
    assert m.params.through == "all" and m.state == "done"
    assert [s for _, s, _ in m.transitions] == [
        "initialise", "takeoff", "detect", "align", "enter", "through", "land", "done"
    ]  # fmt: skip
    assert [r.leg for r in m.plans] == ["enter", "through"]
    idx = passages(flown, CENTRES, NORMALS, SIZES)
    assert None not in idx and idx == sorted(idx)
    np.testing.assert_array_equal(yaw, 0.0)  # the yaw held


def test_stepwise_counts_the_rules_frames_not_the_estimates():
    """frames: 2 while the estimate shows 3: it lands beyond the second, never heading for the third."""
    m, flown, yaw, _ = _fly(TunnelMissionParams(frames=2, through="stepwise"), lambda t, m: [0, 1, 2])
    assert m.state == "done" and m.progress == 2
    idx = passages(flown, CENTRES, NORMALS, SIZES)
    assert idx[0] is not None and idx[1] is not None and idx[2] is None
    assert (flown[-1] - CENTRES[1]) @ NORMALS[1] > 0.9


def test_stepwise_failsafe_while_waiting_lands_clear_of_the_frames():
    """A failsafe's land request while waiting past frame 2 lands there, clear of the bars; during a hop a
    (non-urgent) request is deferred to the rest point past the frame."""
    asked: list[str] = []

    def failsafe_in_second_wait(t: float, m: TunnelMission) -> None:
        if m.state == "wait" and m.progress == 2 and not asked:
            asked.append(m.failsafe(t, "land", "battery low", False))

    m, flown, _, _ = _fly(STEPWISE, lambda t, m: [0, 1], on_step=failsafe_in_second_wait)
    assert asked == [""] and m.state == "aborted" and m.reason == "failsafe: battery low"
    assert 0.15 < (flown[-1] - CENTRES[1]) @ NORMALS[1] < 0.5 and flown[-1][2] < 0.05
    assert frame_boxes(CENTRES, NORMALS, SIZES, 0.05).distance(flown).min() > 0.17
    hop: list[str] = []

    def failsafe_in_hop(t: float, m: TunnelMission) -> None:
        if m.state == "through" and not hop:
            hop.append(m.failsafe(t, "land", "battery low", False))

    m, flown, _, _ = _fly(STEPWISE, lambda t, m: [0, 1, 2], on_step=failsafe_in_hop)
    assert hop and "lands" in hop[0] and m.state == "aborted"
    assert m.progress == 2  # frame 2's hop was finished first
    assert 0.15 < (flown[-1] - CENTRES[1]) @ NORMALS[1] < 0.5 and flown[-1][2] < 0.05


def test_through_is_checked():
    with pytest.raises(ConfigError, match="mission.through must be 'all' or 'stepwise'"):
        TunnelMissionParams(through="some")
    with pytest.raises(ConfigError, match="mission.next_min_m"):
        TunnelMissionParams(next_min_m=-1.0)
    assert math.isclose(TunnelMissionParams().next_min_m, 0.3)


def test_stepwise_waits_until_the_next_frame_is_stable():
    """Frame 2's centre jumps by 3 cm from one estimate to the next (> stable_m, 2 cm) for the first 3 s of the
    wait past frame 1, then holds still: the hop through it is planned only after stable_updates (3) unchanged
    estimates, through the still centre."""
    t_wait: list[float] = []

    def jitter_estimate(t: float, shown: list[int]) -> TunnelEstimate:
        e = _estimate(t, shown)
        if len(shown) > 1 and t_wait and t < t_wait[0] + 3.0:
            c = e.centres_W.copy()
            c[1, 1] += 0.03 * (round(t / (DT * EST_EVERY)) % 2)
            return TunnelEstimate(e.t, c, e.normals_W, e.opening_sizes, e.confidence, e.scans)
        return e

    def shown(t: float, m: TunnelMission) -> list[int]:
        if m.state == "wait" and not t_wait:
            t_wait.append(t)
        return [0, 1] if t_wait else [0]

    m, _, _, _ = _fly(TunnelMissionParams(frames=2, through="stepwise"), shown, estimate=jitter_estimate)
    assert m.state == "done"
    hop = next(r for r in m.plans if r.leg == "through")
    assert hop.t >= t_wait[0] + 3.0 + 2 * DT * EST_EVERY  # the third unchanged estimate after the jitter ended
    np.testing.assert_allclose(m.passed.centres[1], CENTRES[1], atol=1e-12)


def test_stepwise_does_not_skip_an_undetected_frame_beyond_the_rules_gap():
    """Frame 2 is never shown, frame 3 is (2.2 m past frame 1, more than max_gap_m 2 m): past frame 1 the
    mission waits, never plans towards frame 3 (an undetected frame must lie between), times out and lands.
    With max_gap_m 3 m the same estimates take frame 3 as the next one (what the guard prevents)."""
    m, flown, _, _ = _fly(STEPWISE, lambda t, m: [0, 2])
    assert m.state == "aborted" and m.reason.startswith("frame 2 of 3 not detected"), m.reason
    assert [r.leg for r in m.plans] == ["align", "enter"]
    assert np.max((flown - CENTRES[1]) @ NORMALS[1]) < -0.1  # never reached frame 2's plane
    loose = TunnelMissionParams(frames=3, through="stepwise", detect_timeout_s=6.0, max_gap_m=3.0)
    m, _, _, _ = _fly(loose, lambda t, m: [0, 2])
    assert [r.leg for r in m.plans][:3] == ["align", "enter", "through"]
    np.testing.assert_allclose(m.used.centres[-1], CENTRES[2])


def test_stepwise_waits_for_a_nearer_frame_not_yet_confident():
    """Frame 2 is detected but below min_confidence, frame 3 (2.2 m past frame 1, within max_gap_m 3 m here) is
    confident: the next frame is frame 2, waited for (never a hop through it to frame 3, its bars unchecked); once
    frame 2 is confident the mission flies through both in order."""
    loose = TunnelMissionParams(frames=3, through="stepwise", detect_timeout_s=6.0, max_gap_m=3.0)

    def unsure_frame_2(t: float, shown: list[int]) -> TunnelEstimate:
        e = _estimate(t, shown)
        conf = e.confidence.copy()
        conf[1] = 0.1  # < min_confidence (0.2)
        return TunnelEstimate(e.t, e.centres_W, e.normals_W, e.opening_sizes, conf, e.scans)

    m, flown, _, _ = _fly(loose, lambda t, m: [0, 1, 2], estimate=unsure_frame_2)
    assert m.state == "aborted" and m.reason.startswith("frame 2 of 3 not detected"), m.reason
    assert [r.leg for r in m.plans] == ["align", "enter"]
    assert np.max((flown - CENTRES[1]) @ NORMALS[1]) < -0.1  # never reached frame 2's plane
    m, flown, _, _ = _fly(loose, lambda t, m: [0, 1, 2])
    assert m.state == "done" and [r.leg for r in m.plans] == ["align", "enter", "through", "through"]
    idx = passages(flown, CENTRES, NORMALS, SIZES)
    assert None not in idx and idx == sorted(idx), idx


def test_perception_camera_selects_stepwise_and_the_lidar_tunnel_keeps_all():
    from cufund.scenarios import load_scenario

    assert load_scenario("tunnel").mission.params.through == "all"
    cam = load_scenario("tunnel", ["perception=camera", "estimator.kind=vio"])
    assert cam.mission.params.through == "stepwise"
    assert cam.mission.params.frames == 5  # the rest of the mission as the scenario has it
    # a copy with overrides goes through to_dict, which writes through: all: it is overridden, not refused
    lidar = load_scenario("tunnel")
    assert lidar.to_dict()["mission"]["through"] == "all"
    cam = lidar.with_overrides({"perception": "camera", "estimator": {"kind": "vio"}})
    assert cam.mission.params.through == "stepwise"
