"""PoseHistory: the pose at an image's stamp between two estimates, checked against scipy's Slerp and a linear
interpolation of the positions; its bounds (outside the span kept: None), its length bound and its input checks."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from cufund.core.messages import Odometry
from cufund.perception.pose_history import PoseHistory, pose_at, slerp


def _wxyz(r: Rotation) -> np.ndarray:
    return np.roll(r.as_quat(), 1, axis=-1)  # scipy is [x, y, z, w]


def test_lookup_matches_scipy_slerp_and_linear_position() -> None:
    rng = np.random.default_rng(4)
    ts = np.cumsum(rng.uniform(0.002, 0.2, 30))
    rots = Rotation.random(30, random_state=5)
    ps = rng.normal(size=(30, 3)) * 5
    h = PoseHistory(maxlen=100)
    for t, p, q in zip(ts, ps, _wxyz(rots), strict=True):
        # scipy's quaternions are in either hemisphere: the history must still take the short way round
        h.append(t, p, q if rng.random() < 0.5 else -q)
    ref = Slerp(ts, rots)
    t_query = np.concatenate([rng.uniform(ts[0], ts[-1], 200), ts[[0, 7, -1]]])
    for t in t_query:
        pose = h.at(t)
        assert pose is not None
        p, R = pose
        np.testing.assert_allclose(R, ref([t]).as_matrix()[0], atol=1e-9)
        np.testing.assert_allclose(p, [np.interp(t, ts, ps[:, k]) for k in range(3)], atol=1e-9)
    np.testing.assert_allclose(h.position_at(ts[3]), ps[3], atol=1e-12)


def test_pose_at_reads_a_sequence_of_estimates_as_the_history_does() -> None:
    """pose_at on a list of Odometry messages (a component's own deque) gives what PoseHistory gives."""
    rng = np.random.default_rng(7)
    ts = np.cumsum(rng.uniform(0.001, 0.01, 50))
    qs = _wxyz(Rotation.random(50, random_state=8))
    msgs = [Odometry(t, rng.normal(size=3), np.zeros(3), q, np.zeros(3)) for t, q in zip(ts, qs, strict=True)]
    h = PoseHistory()
    h.extend(msgs)
    for t in rng.uniform(ts[0], ts[-1], 50):
        (p, R), (hp, hR) = pose_at(msgs, t), h.at(t)  # type: ignore[misc]
        np.testing.assert_allclose(p, hp, atol=1e-12)
        np.testing.assert_allclose(R, hR, atol=1e-12)
    assert pose_at(msgs, ts[0] - 1e-3) is None and pose_at([], 0.0) is None


def test_slerp_keeps_a_constant_rate_where_nlerp_would_not() -> None:
    # a 170 deg turn about z: the midway-quarter point of slerp is at 42.5 deg; a normalised linear blend is not
    q0, q1 = np.array([1.0, 0, 0, 0]), _wxyz(Rotation.from_euler("z", 170, degrees=True))
    got = Rotation.from_quat(np.roll(slerp(q0, q1, 0.25), -1)).as_euler("zyx", degrees=True)[0]
    assert got == pytest.approx(42.5, abs=1e-9)
    nlerp = 0.75 * q0 + 0.25 * q1
    assert Rotation.from_quat(np.roll(nlerp, -1)).as_euler("zyx", degrees=True)[0] != pytest.approx(42.5, abs=1.0)
    np.testing.assert_allclose(slerp(q0, q0, 0.3), q0)  # no angle: no division by sin(0)


def test_outside_the_span_kept_there_is_no_pose_and_the_oldest_go() -> None:
    h = PoseHistory(maxlen=3)
    assert h.at(0.0) is None and h.t_first is None and len(h) == 0
    q = np.array([1.0, 0, 0, 0])
    for k in range(5):
        h.append(float(k), [float(k), 0, 0], q)
    assert len(h) == 3 and (h.t_first, h.t_last) == (2.0, 4.0)
    assert h.at(1.9) is None and h.at(4.1) is None and h.at(float("nan")) is None
    np.testing.assert_allclose(h.position_at(2.5), [2.5, 0, 0])
    h.append(4.0, [4.0, 0, 0], q)  # a repeated stamp is kept
    np.testing.assert_allclose(h.position_at(4.0), [4.0, 0, 0])
    h.clear()
    assert len(h) == 0


@pytest.mark.parametrize(
    ("args", "field"),
    [
        ((float("nan"), [0, 0, 0], [1, 0, 0, 0]), "t must"),
        ((1.0, [0, 0], [1, 0, 0, 0]), "p_W"),
        ((1.0, [0, float("inf"), 0], [1, 0, 0, 0]), "p_W"),
        ((1.0, [0, 0, 0], [2, 0, 0, 0]), "q_WB"),
        ((1.0, [0, 0, 0], [1, 0, 0]), "q_WB"),
        ((-1.0, [0, 0, 0], [1, 0, 0, 0]), "back in time"),
    ],
)
def test_bad_poses_are_refused_naming_the_field(args: tuple, field: str) -> None:
    h = PoseHistory()
    h.append(0.0, [0, 0, 0], [1, 0, 0, 0])
    with pytest.raises(ValueError, match=field):
        h.append(*args)
    assert len(h) == 1


@pytest.mark.parametrize("maxlen", [0, -1, 2.5, True, "3"])
def test_a_bad_length_is_refused(maxlen: object) -> None:
    with pytest.raises(ValueError, match="maxlen"):
        PoseHistory(maxlen=maxlen)  # type: ignore[arg-type]


def test_extend_skips_stale_and_repeated_estimates_from_the_bus() -> None:
    """A bus may hand over an estimate older than (or as old as) the newest kept: extend skips it (append refuses)."""
    q = [1.0, 0.0, 0.0, 0.0]
    z = np.zeros(3)
    msgs = [Odometry(t, np.array([t, 0.0, 0.0]), z, np.array(q), z) for t in (0.0, 1.0, 0.5, 1.0, 2.0)]
    h = PoseHistory()
    h.extend(msgs)
    assert len(h) == 3 and (h.t_first, h.t_last) == (0.0, 2.0)
    np.testing.assert_allclose(h.position_at(0.75), [0.75, 0, 0])  # the stale 0.5 s estimate did not enter
    with pytest.raises(ValueError, match="back in time"):
        h.append(1.5, [0, 0, 0], q)
