"""The search mission (issue 26): association gating, two-view confirmation, the metrics against hand-computed
cases, the coverage reference and the world's people."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cufund.core.bus import Bus, BusView
from cufund.core.config import ConfigError
from cufund.core.messages import Detections3D, Odometry, Topics
from cufund.missions.search import SearchMission, SearchParams, search_reference
from cufund.missions.search_tracks import SearchTracker, SearchTrackParams, search_metrics
from cufund.worlds.search_forest import people_positions, search_forest

PARAMS = SearchTrackParams(gate_m=2.0, min_baseline_m=3.0, agree_m=1.5)


# --- metrics ------------------------------------------------------------------------------------------------
def test_metrics_hand_computed():
    """People at (0,0,0), (10,0,0), (0,10,0); finds at (0.3,0.4,0) (0.5 m off the first), (10,1.2,0) (1.2 m off
    the second), (30,30,0) (nothing near): 2 of 3 finds right, 2 of 3 people found, errors 0.5 and 1.2 m."""
    people = np.array([[0, 0, 0], [10, 0, 0], [0, 10, 0]], float)
    found = np.array([[0.3, 0.4, 0], [10, 1.2, 0], [30, 30, 0]], float)
    m = search_metrics(found, people, match_m=2.0, t_found=42.5)
    assert m["search_precision"] == pytest.approx(2 / 3)
    assert m["search_recall"] == pytest.approx(2 / 3)
    assert m["search_position_error_m"] == pytest.approx([0.5, 1.2])
    assert m["search_time_s"] == 42.5


def test_metrics_pair_one_to_one_and_gate():
    """Two finds near one person: only one counts (precision 1/2); a find 2.5 m off with match_m 2 counts for
    nothing; no finds: precision 1 (nothing claimed), recall 0, no time."""
    people = np.array([[0, 0, 0]], float)
    m = search_metrics(np.array([[0.2, 0, 0], [0, 0.3, 0]]), people, 2.0)
    assert (m["search_precision"], m["search_recall"], m["search_position_error_m"]) == (0.5, 1.0, [0.2])
    m = search_metrics(np.array([[2.5, 0, 0]]), people, 2.0)
    assert (m["search_precision"], m["search_recall"], m["search_position_error_m"]) == (0.0, 0.0, [])
    m = search_metrics(np.zeros((0, 3)), people, 2.0)
    assert (m["search_precision"], m["search_recall"], m["search_time_s"]) == (1.0, 0.0, None)


def test_metrics_pairing_is_the_best_one_to_one_not_greedy():
    """Finds A (0.5, 0) and B (-1.5, 0); people P (0, 0) and Q (2, 0), match 2 m: the nearest pair is A-P (0.5 m),
    so greedy matching (nearest pair first, or each find in turn taking its nearest person) pairs it and leaves B
    3.5 m from Q, unmatched; the one-to-one assignment pairs A-Q (1.5) and B-P (1.5): both count."""
    m = search_metrics(np.array([[0.5, 0, 0], [-1.5, 0, 0]]), np.array([[0, 0, 0], [2, 0, 0]]), 2.0)
    assert m["search_precision"] == 1.0 and m["search_recall"] == 1.0
    assert m["search_position_error_m"] == pytest.approx([1.5, 1.5])


# --- association and two-view confirmation -------------------------------------------------------------------
def test_one_view_is_not_confirmed():
    tr = SearchTracker(PARAMS)
    tr.add(0.0, [5, 5, 0.8], [0, 0, 12])
    assert len(tr.tracks) == 1 and tr.confirmed() == [] and len(tr.found()) == 0


def test_two_close_views_are_not_confirmed():
    """Many detections that agree, all from camera positions within 2 m of each other (< 3 m): not confirmed."""
    tr = SearchTracker(PARAMS)
    for k in range(10):
        tr.add(0.1 * k, [5, 5, 0.8], [0.2 * k, 0, 12])
    assert len(tr.tracks) == 1 and tr.confirmed() == []


def test_two_separated_views_that_agree_are_confirmed():
    """Views from cameras 4 m apart, positions 0.6 m apart: confirmed at the second, found at their mean."""
    tr = SearchTracker(PARAMS)
    tr.add(1.0, [5.0, 5.0, 0.8], [0, 0, 12])
    tr.add(2.5, [5.6, 5.0, 0.8], [4, 0, 12])
    (track,) = tr.confirmed()
    assert track.confirmed_at == 2.5
    np.testing.assert_allclose(tr.found(), [[5.3, 5.0, 0.8]])


def test_separated_views_that_disagree_are_not_confirmed():
    """Cameras 4 m apart, positions 1.8 m apart (> agree 1.5 m, within the 2 m gate): one track, not confirmed;
    the third view agreeing with the first from far enough confirms it."""
    tr = SearchTracker(PARAMS)
    tr.add(1.0, [5.0, 5.0, 0.8], [0, 0, 12])
    tr.add(2.0, [6.8, 5.0, 0.8], [4, 0, 12])
    assert len(tr.tracks) == 1 and tr.confirmed() == []
    tr.add(3.0, [5.2, 5.0, 0.8], [8, 0, 12])
    assert len(tr.confirmed()) == 1


def test_confirmation_waits_for_enough_strong_detections():
    """confirm_score 0.5, min_strong 2: two weak views 4 m apart that agree are tracked but not confirmed; one
    strong view more is not enough, the second strong one confirms (at its time); weak views still join the
    track (they extend it) and the find is the mean of all of them. Without confirm_score the two weak views
    confirm at once (the default: every detection kept is strong)."""
    p = SearchTrackParams(gate_m=2.0, min_baseline_m=3.0, agree_m=1.5, min_score=0.2, confirm_score=0.5, min_strong=2)
    tr = SearchTracker(p)
    tr.add(1.0, [5.0, 5.0, 0.8], [0, 0, 12], score=0.3)
    tr.add(2.0, [5.2, 5.0, 0.8], [4, 0, 12], score=0.3)
    (track,) = tr.tracks
    assert track.two_views and track.strong == 0 and tr.confirmed() == []
    tr.add(3.0, [5.4, 5.0, 0.8], [5, 0, 12], score=0.6)
    assert tr.confirmed() == []
    tr.add(4.0, [5.6, 5.0, 0.8], [6, 0, 12], score=0.5)
    assert [k.confirmed_at for k in tr.confirmed()] == [4.0]
    np.testing.assert_allclose(tr.found(), [[5.3, 5.0, 0.8]])
    plain = SearchTracker(SearchTrackParams(min_score=0.2))
    plain.add(1.0, [5.0, 5.0, 0.8], [0, 0, 12], score=0.3)
    plain.add(2.0, [5.2, 5.0, 0.8], [4, 0, 12], score=0.3)
    assert [k.confirmed_at for k in plain.confirmed()] == [2.0]


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"min_score": 0.4, "confirm_score": 0.3}, "confirm_score must be a number in \\[min_score, 1\\]"),
        ({"confirm_score": 1.5}, "confirm_score"),
        ({"min_strong": 0}, "min_strong must be an integer in \\[1, 1000\\]"),
        ({"min_strong": 2.5}, "min_strong"),
        ({"min_strong": True}, "min_strong"),
    ],
)
def test_confirmation_params_are_checked(kw: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        SearchTrackParams(**kw)


def test_association_gates_by_distance():
    """A detection 2.5 m from a track (gate 2 m) starts a new one; 1.9 m away joins the nearest track."""
    tr = SearchTracker(PARAMS)
    a = tr.add(0.0, [0, 0, 0], [0, -10, 12])
    b = tr.add(0.1, [2.5, 0, 0], [0, -10, 12])
    assert a is not b and len(tr.tracks) == 2
    c = tr.add(0.2, [0.6, 1.8, 0], [5, -10, 12])  # 1.9 m from a's mean, 2.6 m from b's
    assert c is a and len(a.positions) == 2
    d = tr.add(0.3, [2.2, 0.3, 0], [5, -10, 12])  # nearer b
    assert d is b
    with pytest.raises(ValueError, match="p_W must be 3 finite numbers"):
        tr.add(0.4, [np.nan, 0, 0], [0, 0, 0])
    with pytest.raises(ValueError, match="gate_m must be a finite number > 0"):
        SearchTrackParams(gate_m=0.0)


# --- the flight-software component ----------------------------------------------------------------------------
def test_mission_takes_person_detections_with_the_camera_at_the_capture_time():
    """Detections3D of two classes: only 'person' ones scored >= min_score and placed within the height band
    (-0.5 to 1.6 m above the take-off point) go to the tracker, each with the estimate's position at its stamp;
    two views from estimates 4 m apart confirm one find."""
    m = SearchMission(SearchParams())
    bus = Bus()
    view = BusView(bus, m.name, m.inputs + m.optional_inputs, m.outputs, deny_truth=True)
    m.reset()
    m.setup(view)
    q = np.array([1.0, 0, 0, 0])
    for t in np.arange(0.0, 2.01, 0.1):
        bus.publish(Topics.ESTIMATE, Odometry(t, np.array([2.0 * t, 0, 12]), np.zeros(3), q, np.zeros(3)))
    names = ("person", "car")
    for t, x in ((0.0, 5.0), (2.0, 5.4)):  # cameras at x = 0 and 4 m
        c = np.array([[x, 5.0, 0.8], [9.0, 9.0, 0.5], [20.0, 20.0, 0.8], [30.0, 5.0, 2.0], [30.0, 9.0, -0.6]])
        scores = np.array([0.9, 0.9, 0.1, 0.9, 0.9], np.float32)  # a car, a low score, above and below the band
        bus.publish(Topics.DETECTIONS_3D, Detections3D(t, c, np.ones((5, 2)), scores, np.array([0, 1, 0, 0, 0]), names))
    m.step(2.0, view)
    assert m.detections == 2 and len(m.tracker.tracks) == 1
    (track,) = m.tracker.confirmed()
    np.testing.assert_allclose(track.cameras, [[0, 0, 12], [4, 0, 12]], atol=1e-9)
    (f,) = m.found()
    assert f["p_W"] == pytest.approx([5.2, 5.0, 0.8]) and f["confirmed_at_s"] == 2.0 and f["detections"] == 2


# --- the reference and the world ------------------------------------------------------------------------------
def test_reference_climbs_covers_the_area_facing_along_each_lane_and_lands():
    p = SearchParams(area=((-10, -6), (10, -6), (10, 6), (-10, 6)), altitude=12.0, spacing=4.0)
    ref, path, (t0, t1) = search_reference(p, np.array([1.0, 2.0, 0.0]))
    assert len(path) == 6  # 3 lanes 4 m apart over 12 m, each two waypoints
    np.testing.assert_allclose(sorted(set(path[:, 1].round(6))), [-4.0, 0.0, 4.0])
    t = np.arange(ref.t_start, ref.t_end, 0.01)
    s = ref.sample(t)
    assert np.all(np.isfinite(s.p_W)) and s.p_W[:, 2].max() == pytest.approx(12.0)
    np.testing.assert_allclose(s.p_W[0], [1, 2, 0], atol=1e-9)
    np.testing.assert_allclose(ref.sample(ref.t_end).p_W[0], [1, 2, 0], atol=1e-6)
    moving = np.linalg.norm(s.v_W[:, :2], axis=1) > 0.5
    heading = np.arctan2(s.v_W[moving, 1], s.v_W[moving, 0])
    yaw_err = np.abs(np.remainder(s.yaw[moving] - heading + np.pi, 2 * np.pi) - np.pi)
    assert yaw_err.max() < 1e-6  # the camera looks along every leg while the vehicle moves
    assert np.abs(np.diff(s.yaw)).max() < 0.02  # no step in yaw (0.8 rad/s peak x 10 ms)
    # every lane's ends are flown through at altitude
    for w in path:
        assert np.min(np.linalg.norm(s.p_W - w, axis=1)) < 1e-3
    assert np.linalg.norm(s.v_W, axis=1).max() <= p.v_max + 1e-6
    # the search window: from the arrival at the first lane's start to the end of the last lane
    np.testing.assert_allclose(ref.sample(t0).p_W[0], path[0], atol=1e-6)
    np.testing.assert_allclose(ref.sample(t1).p_W[0], path[-1], atol=1e-6)
    lanes = (t >= t0) & (t <= t1)
    assert np.all(np.abs(s.p_W[lanes, 2] - 12.0) < 1e-6) and 0 < t0 < t1 < ref.t_end


def test_mission_ignores_boxes_larger_than_max_box_m():
    """max_box_m 2.4: a person box 2.6 m tall (or 2.5 m wide) at its depth is ignored, one 2.3 m x 1.0 m is
    kept; with no limit (the default) all three count."""
    for limit, kept in ((2.4, 1), (None, 3)):
        m = SearchMission(SearchParams(max_box_m=limit))
        bus = Bus()
        view = BusView(bus, m.name, m.inputs + m.optional_inputs, m.outputs, deny_truth=True)
        m.reset()
        m.setup(view)
        for t in (0.0, 1.0):
            q = np.array([1.0, 0, 0, 0])
            bus.publish(Topics.ESTIMATE, Odometry(t, np.array([0.0, 0, 12]), np.zeros(3), q, np.zeros(3)))
        c = np.array([[5.0, 5.0, 0.8], [-5.0, 5.0, 0.8], [5.0, -5.0, 0.8]])
        sizes = np.array([[1.0, 2.3], [1.0, 2.6], [2.5, 1.0]])
        bus.publish(
            Topics.DETECTIONS_3D,
            Detections3D(0.5, c, sizes, np.full(3, 0.9, np.float32), np.zeros(3, int), ("person",)),
        )
        m.step(1.0, view)
        assert m.detections == kept


def test_turn_between_legs_is_a_hold_turning_the_short_way_at_the_peak_rate():
    """planning.sequence.Hold.turn (the search's turn between legs): from 170 deg to -170 deg is a 20 deg turn the
    short way; the position holds, the rate peaks at yaw_rate, integrates (trapezoid) to the turn and is 0 at both
    ends; a Hold without yaw_end keeps its heading."""
    from cufund.planning.sequence import Hold

    p = np.array([1.0, 2.0, 12.0])
    h = Hold.turn(p, math.radians(170), math.radians(-170), 0.8, t_start=3.0)
    t = np.linspace(h.t_start - 0.5, h.t_end + 0.5, 20001)
    s = h.sample(t)
    np.testing.assert_allclose(s.p_W, np.tile(p, (len(t), 1)))
    assert np.abs(s.yaw_rate).max() == pytest.approx(0.8, rel=1e-6)
    assert np.trapezoid(s.yaw_rate, t) == pytest.approx(math.radians(20), rel=1e-6)
    assert s.yaw[-1] - s.yaw[0] == pytest.approx(math.radians(20), rel=1e-9) and s.yaw_rate[[0, -1]].tolist() == [0, 0]
    still = Hold(p, 2.0, 0.3).sample(np.array([0.0, 1.0]))
    assert still.yaw.tolist() == [0.3, 0.3] and still.yaw_rate.tolist() == [0.0, 0.0]
    with pytest.raises(ValueError, match="yaw_rate"):
        Hold.turn(p, 0.0, 1.0, 0.0)


def test_lanes_run_lead_m_beyond_the_area_and_finds_outside_it_are_ignored():
    """lead_m 5: each lane's ends lie 5 m beyond the area's edges along the lane; a detection 1.5 m outside the
    area (margin 1 m) is ignored, one 0.5 m outside counts; one captured after the search window is ignored."""
    p = SearchParams(area=((-10, -6), (10, -6), (10, 6), (-10, 6)), spacing=4.0, heading=0.0, lead_m=5.0)
    _, path, _ = search_reference(p, np.zeros(3))
    np.testing.assert_allclose(sorted(set(np.abs(path[:, 0]).round(6))), [15.0])
    m = SearchMission(p, window=(0.2, 0.8))
    bus = Bus()
    view = BusView(bus, m.name, m.inputs + m.optional_inputs, m.outputs, deny_truth=True)
    m.reset()
    m.setup(view)
    for t in (0.0, 1.0):
        bus.publish(
            Topics.ESTIMATE, Odometry(t, np.array([0.0, 0, 12]), np.zeros(3), np.array([1.0, 0, 0, 0]), np.zeros(3))
        )
    c = np.array([[11.5, 0.0, 0.8], [10.5, 0.0, 0.8]])
    bus.publish(
        Topics.DETECTIONS_3D,
        Detections3D(0.5, c, np.ones((2, 2)), np.full(2, 0.9, np.float32), np.zeros(2, int), ("person",)),
    )
    late = Detections3D(0.9, c[1:], np.ones((1, 2)), np.full(1, 0.9, np.float32), np.zeros(1, int), ("person",))
    bus.publish(Topics.DETECTIONS_3D, late)  # after the window (going home): ignored
    m.step(1.0, view)
    assert m.detections == 1 and m.tracker.tracks[0].positions[0][0] == 10.5


def test_params_are_checked():
    with pytest.raises(ConfigError, match="mission.altitude"):
        SearchParams(altitude=-1.0)
    with pytest.raises(ConfigError, match="mission.area"):
        SearchParams(area=((0, 0), (1, 1)))
    with pytest.raises(ConfigError, match="mission.tracks"):
        SearchParams(tracks={"gate_m": -1})  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="mission.max_box_m must be a finite number > 0"):
        SearchParams(max_box_m=0.0)


def test_search_forest_places_k_separated_people():
    """K people, seeded (same seed, same places), at least about 'separation' apart, inside the margin."""
    w = search_forest(seed=3, people=6, beside_trees=0.5, separation=4.0)
    people = people_positions(w)
    assert people.shape == (6, 3)
    np.testing.assert_allclose(people, people_positions(search_forest(seed=3, people=6, beside_trees=0.5)))
    assert not np.allclose(people, people_positions(search_forest(seed=4, people=6, beside_trees=0.5)))
    d = np.linalg.norm(people[:, None, :2] - people[None, :, :2], axis=2) + np.eye(6) * 99
    assert d.min() > 4.0 - 2 * 1.5  # drawn squares' centres 4 m apart, each person within 1.5 m of its centre
    assert np.all(np.abs(people[:, :2]) <= 20 - 4 + 1e-9)


def _gap_to_trunks(world) -> np.ndarray:
    """Each person's (in placement order) nearest mesh vertex to a trunk's axis, horizontally [m]."""
    trunks = np.array([o.vertices.mean(0)[:2] for o in world.objects if o.label == "tree"])
    people = [o.vertices[:, :2] for o in world.objects if o.label == "person"]
    return np.array([np.linalg.norm(v[:, None] - trunks[None], axis=2).min() for v in people])


def test_search_forest_places_the_share_asked_for_beside_a_trunk():
    """beside_trees 0.5 of 6 people, beside_m 0.5: the first 3 placed stand within the 0.5 m square about a
    trunk's axis (a vertex within its half-diagonal); placed at random instead (beside_trees 0), one of the same
    seed's first 3 is not (the check tells the two apart: the forest has a trunk every ~11 m^2)."""
    bound = 0.5 * math.sqrt(2) + 0.1
    gaps = _gap_to_trunks(search_forest(seed=3, people=6, beside_trees=0.5, beside_m=0.5))
    assert np.all(gaps[:3] <= bound), gaps
    assert not np.all(_gap_to_trunks(search_forest(seed=3, people=6, beside_trees=0.0, beside_m=0.5))[:3] <= bound)


# --- end to end ---------------------------------------------------------------------------------------------
SHORT = [
    "world.people=1",
    "world.size=20.0",
    "world.margin=7.0",
    "mission.area=[[-5, -3], [5, -3], [5, 3], [-5, 3]]",
    "duration=80.0",
]
"""A shortened search (one person in a 20 m forest, one lane; docs/guides/search.md runs it too): the built-in
one takes minutes."""


def test_search_scenario_has_one_setpoint_publisher():
    """The built-in search publishes trajectory setpoints from the mission's follower alone (the default
    ``waypoints`` planner's follower also flew its 1 m square beside it: two streams on one topic, the land
    detector watching the square's follower), and a scenario giving the search a planner is refused."""
    from cufund.missions.land_detector import LandDetectorComponent
    from cufund.scenarios.build import build_simulation
    from cufund.scenarios.schema import load_scenario

    built = build_simulation(load_scenario("search", SHORT))
    comps = built.simulator.components
    writers = [c for c in comps if str(Topics.TRAJECTORY_SETPOINT) in map(str, getattr(c, "writes", c.outputs))]
    assert len(writers) == 1, [type(c).__name__ for c in writers]
    (detector,) = [c for c in comps if isinstance(c, LandDetectorComponent)]
    assert detector.follower is writers[0]
    with pytest.raises(ConfigError, match="set planner: null"):
        build_simulation(load_scenario("search", [*SHORT, "planner=waypoints"]))


def test_search_end_to_end_shortened(tmp_path):
    """`search` shortened, with the shipped people model on the stereo pair and the estimate: the run completes,
    the person is found from two views (recall 1, precision 1) within 1 m and found_people.json holds the find
    (test_no_truth_reads checks the built-in scenario reads no truth)."""
    import json

    from cufund.scenarios.build import build_simulation
    from cufund.scenarios.run_folder import run_into_folder
    from cufund.scenarios.schema import load_scenario

    built = build_simulation(load_scenario("search", SHORT))
    run = run_into_folder(built, tmp_path, log=False, plots=False, replay=False, progress=False)  # found_people.json
    m = run.metrics
    assert run.result.status.value == "completed"
    assert m["search_people"] == 1 and m["search_finds"] == 1
    search = {k: v for k, v in m.items() if k.startswith("search")}
    assert m["search_recall"] == 1.0 and m["search_precision"] == 1.0, search
    assert len(m["search_position_error_m"]) == 1 and max(m["search_position_error_m"]) < 1.0
    assert 0 < m["search_time_s"] < run.result.sim_time_s
    found = json.loads((tmp_path / "found_people.json").read_text())["found"]
    assert len(found) == 1 and found[0]["detections"] >= 2


def _bench_search():
    """benchmarks/bench_search.py as a module (benchmarks/ is no package)."""
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_search.py"
    spec = importlib.util.spec_from_file_location("bench_search", path)
    assert spec is not None and spec.loader is not None
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench


def test_benchmark_totals_count_every_find():
    """benchmarks/bench_search.py pools the finds from each run's search_finds: a seed whose 3 finds are all wrong
    (precision 0) counts 3 finds (its finds were derived from right / precision, and so counted none), one with no
    finds none, and a run that raised nothing."""
    bench = _bench_search()
    wrong = {"search_precision": 0.0, "search_position_error_m": [], "search_people": 5, "search_finds": 3}
    assert bench._counts(wrong) == (3, 0, 5)
    none = {"search_precision": 1.0, "search_position_error_m": [], "search_people": 5, "search_finds": 0}
    assert bench._counts(none) == (0, 0, 5)
    assert bench._counts({"status": "exception: ValueError: x"}) == (0, 0, 0)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--set", "nope=1"], "unknown key 'nope'"),
        (["--set", "mission.max_box_m=0"], "mission.max_box_m"),
        (["--set", "seed=3"], "--first and --seeds"),
        (["--first", "-1"], "seed must be an integer"),
        (["--jobs", "3"], "--jobs"),
    ],
)
def test_benchmark_refuses_bad_arguments_before_flying(argv, message, monkeypatch, capsys):
    """A bad --set (an unknown key, a refused value, the seed every run would share) or seed range exits 2 naming
    it before any run starts (a bad --set failed in every worker, one exception row per seed, and exited 0)."""
    bench = _bench_search()
    monkeypatch.setattr("sys.argv", ["bench_search.py", *argv])
    monkeypatch.setattr(bench.mp, "get_context", lambda *a: pytest.fail("a run was started"))
    with pytest.raises(SystemExit) as e:
        bench.main()
    assert e.value.code == 2 and message in capsys.readouterr().err
