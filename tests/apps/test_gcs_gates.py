"""The ground station shows and offers the gates the vehicle detected (its tunnel estimate, in its estimated frame,
updated as frames are found), never the true course: on the tunnel scenario's real build, with the detector's
estimate set by the test."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from cufund.apps.gcs.mission_preview import preview_mission
from cufund.apps.gcs.session import GcsSession
from cufund.apps.live import LiveRun
from cufund.core.messages import Topics, TunnelEstimate
from cufund.missions.tunnel_kind import course_of


class DetectorFeed:
    """The live run of a scenario (built, not started) whose latest tunnel estimate the test sets."""

    def __init__(self, scenario: str) -> None:
        self.run = LiveRun(scenario, start=False)
        self.built, self.config = self.run.built, self.run.config
        self.estimate: TunnelEstimate | None = None

    def latest(self, topic: str) -> Any:
        return self.estimate if str(topic) == str(Topics.TUNNEL_ESTIMATE) else None


def _estimate(centres, t=3.0, scans=10) -> TunnelEstimate:
    k = len(centres)
    return TunnelEstimate(
        t=t,
        centres_W=np.array(centres, dtype=float).reshape(k, 3),
        normals_W=np.tile([1.0, 0.0, 0.0], (k, 1)),
        opening_sizes=np.tile([0.4, 0.4], (k, 1)),
        confidence=np.linspace(0.5, 0.9, k),
        scans=scans,
    )


@pytest.fixture(scope="module")
def tunnel():
    feed = DetectorFeed("tunnel")
    return feed, GcsSession(feed, "tunnel"), course_of(feed.config)


def test_nothing_is_offered_before_a_detection_and_the_true_frames_are_not_drawn(tunnel):
    feed, session, course = tunnel
    feed.estimate = None
    assert session.new_gates() is None and session.regions() == []
    scene = session.scene()
    labels = {m["label"] for m in scene["meshes"]}
    assert "tunnel_frame" not in labels and {"floor", "wall"} <= labels  # the room stays, the course does not
    assert scene["world_truth"] is True and scene["gates"] == [] and scene["regions"] == []
    assert len(course.frames) == 5  # there is a true course it could have shown


def test_the_detected_gates_are_shown_and_offered_where_the_vehicle_believes_they_are(tunnel):
    """The estimate is 0.3 m off the true course: the ground station follows the estimate."""
    feed, session, course = tunnel
    true = np.array([f.centre_W for f in course.frames[:2]])
    believed = true + [0.0, 0.3, 0.0]
    feed.estimate = _estimate(believed)
    msg = session.new_gates()
    assert msg is not None and msg["type"] == "gates" and msg["frame"] == "estimated"
    assert [g["name"] for g in msg["gates"]] == ["gate1", "gate2"]
    np.testing.assert_allclose([g["centre_W"] for g in msg["gates"]], believed, atol=1e-3)
    regions = session.regions()
    assert [r.name for r in regions] == ["gate1", "gate2"]
    np.testing.assert_allclose([r.centre_W for r in regions], believed, atol=1e-3)
    assert session.new_gates() is None  # unchanged: nothing more to send
    plan = preview_mission({"formula": "F(gate2)"}, regions, np.zeros(3))
    np.testing.assert_allclose(plan["waypoints_W"][-1], believed[1], atol=1e-3)
    with pytest.raises(ValueError, match="gate3"):  # not detected yet: not a region
        preview_mission({"formula": "F(gate3)"}, regions, np.zeros(3))
    assert session.scene()["gates"] == msg["gates"]


def test_the_gates_update_as_frames_are_found(tunnel):
    feed, session, course = tunnel
    centres = [f.centre_W for f in course.frames]
    feed.estimate = _estimate(centres[:3], t=5.0, scans=30)
    first = session.new_gates()
    assert first is not None and len(first["gates"]) == 3
    feed.estimate = _estimate(centres, t=7.0, scans=50)
    more = session.new_gates()
    assert more is not None and [g["name"] for g in more["gates"]] == [f"gate{k + 1}" for k in range(5)]
    assert len(session.regions()) == 5


def test_a_run_without_a_detector_draws_its_whole_world():
    feed = DetectorFeed("vehicle")
    session = GcsSession(feed, "vehicle")
    assert not session.detects_gates
    assert any(m["label"] == "tunnel_frame" for m in session.scene()["meshes"])  # a known arena, not a search
    assert session.regions() == []
