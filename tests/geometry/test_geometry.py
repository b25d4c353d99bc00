"""cufund.geometry against scipy.spatial.transform.Rotation (an independent implementation; scipy's quaternions are
[x, y, z, w], ours [w, x, y, z]) and against analytic cases: the identity, half turns about each axis, the
near-singular branches of Shepperd's method, round trips, composition and inverses, and bad input."""

from __future__ import annotations

import math
import subprocess
import sys
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp

from cufund import geometry
from cufund.geometry import (
    Transform,
    attitude_from_thrust_and_yaw,
    cross,
    homogeneous,
    interpolate_poses,
    quat_conjugate,
    quat_from_matrix,
    quat_from_two_vectors,
    quat_mul,
    quat_to_matrix,
    sample_poses,
    unit_quaternion,
    world_to_body,
    yaw_of,
    yaw_quaternion,
)

IDENTITY_Q = np.array([1.0, 0.0, 0.0, 0.0])


def scipy_rot(q_wxyz: np.ndarray) -> Rotation:
    return Rotation.from_quat(np.asarray(q_wxyz)[..., [1, 2, 3, 0]])


def wxyz(r: Rotation) -> np.ndarray:
    return r.as_quat()[..., [3, 0, 1, 2]]


def same_rotation(q_a: np.ndarray, q_b: np.ndarray, atol: float = 1e-12) -> bool:
    """q and -q are one rotation."""
    return bool(np.allclose(q_a, q_b, atol=atol) or np.allclose(q_a, -q_b, atol=atol))


@pytest.fixture
def quats(rng: np.random.Generator) -> np.ndarray:
    q = rng.standard_normal((200, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


# --- quat_to_matrix ------------------------------------------------------------------------------------------------


def test_quat_to_matrix_matches_scipy_one_and_batch(quats):
    R_ref = scipy_rot(quats).as_matrix()
    np.testing.assert_allclose(quat_to_matrix(quats), R_ref, atol=1e-14)
    for q, R in zip(quats[:20], R_ref[:20], strict=True):
        np.testing.assert_allclose(quat_to_matrix(q), R, atol=1e-14)
    # a (2, 100, 4) batch keeps its leading axes
    assert quat_to_matrix(quats.reshape(2, 100, 4)).shape == (2, 100, 3, 3)


def test_quat_to_matrix_one_and_batch_agree_bit_for_bit(quats):
    one = np.array([quat_to_matrix(q) for q in quats])
    assert np.array_equal(one, quat_to_matrix(quats))
    scaled = quats * np.linspace(0.5, 3.0, len(quats))[:, None]
    one = np.array([quat_to_matrix(q, normalize=True) for q in scaled])
    assert np.array_equal(one, quat_to_matrix(scaled, normalize=True))


def test_quat_to_matrix_analytic_cases():
    np.testing.assert_array_equal(quat_to_matrix(IDENTITY_Q), np.eye(3))
    np.testing.assert_array_equal(quat_to_matrix([0.0, 1.0, 0.0, 0.0]), np.diag([1.0, -1.0, -1.0]))  # half turn x
    np.testing.assert_array_equal(quat_to_matrix([0.0, 0.0, 1.0, 0.0]), np.diag([-1.0, 1.0, -1.0]))
    np.testing.assert_array_equal(quat_to_matrix([0.0, 0.0, 0.0, 1.0]), np.diag([-1.0, -1.0, 1.0]))
    c = math.cos(math.pi / 4)  # a quarter turn about z takes body x to world y
    np.testing.assert_allclose(quat_to_matrix([c, 0.0, 0.0, c]) @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)


def test_quat_to_matrix_normalize(quats):
    np.testing.assert_allclose(quat_to_matrix(3.0 * quats[0], normalize=True), quat_to_matrix(quats[0]), atol=1e-15)
    with pytest.raises(ValueError, match="q_AB must be unit quaternions"):
        quat_to_matrix(3.0 * quats[0])
    with pytest.raises(ValueError, match="q_AB must be unit quaternions"):
        quat_to_matrix(3.0 * quats)


@pytest.mark.parametrize(
    "bad, message",
    [
        ([1.0, 0.0, 0.0], r"q_AB must have shape \(4,\)"),
        (np.zeros((3, 3)), r"q_AB must have shape \(4,\)"),
        (1.0, r"q_AB must have shape \(4,\)"),
        ([0.0, 0.0, 0.0, 0.0], "q_AB must be non-zero"),
        ([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]], "q_AB must be non-zero"),
        ([math.nan, 0.0, 0.0, 1.0], "q_AB must be finite"),
        ([[1.0, 0.0, 0.0, math.inf]], "q_AB must be finite"),
        (["a", "b", "c", "d"], "q_AB must be an array of numbers"),
    ],
)
def test_quat_to_matrix_bad_input(bad, message):
    with pytest.raises(ValueError, match=message):
        quat_to_matrix(bad)
    with pytest.raises(ValueError, match=message):
        quat_to_matrix(bad, normalize=True)


# --- quat_from_matrix (Shepperd) ------------------------------------------------------------------------------------


def test_quat_from_matrix_matches_scipy(quats):
    R = scipy_rot(quats).as_matrix()
    q_ref = wxyz(Rotation.from_matrix(R))
    q_ref = np.where(q_ref[:, :1] < 0, -q_ref, q_ref)  # ours has w >= 0
    np.testing.assert_allclose(quat_from_matrix(R), q_ref, atol=1e-14)
    for Ri, qi in zip(R[:20], q_ref[:20], strict=True):
        np.testing.assert_allclose(quat_from_matrix(Ri), qi, atol=1e-14)


def _near_half_turns() -> list[np.ndarray]:
    """Rotations whose trace is at or near -1 (w ≈ 0), where only the branch of the largest diagonal entry is
    accurate: half turns and half turns less 1e-9 rad about x, y, z and about axes dominated by each of them."""
    axes = [np.eye(3)[i] for i in range(3)] + [
        np.array(a) / np.linalg.norm(a) for a in ([1.0, 0.3, 0.2], [0.2, 1.0, -0.3], [-0.1, 0.3, 1.0], [1.0, 1.0, 1.0])
    ]
    return [axis * angle for axis in axes for angle in (math.pi, math.pi - 1e-9, math.pi - 1e-4)]


@pytest.mark.parametrize("rotvec", _near_half_turns(), ids=lambda v: np.array2string(v, precision=3))
def test_quat_from_matrix_near_singular_branches(rotvec):
    R = Rotation.from_rotvec(rotvec).as_matrix()
    q = quat_from_matrix(R)
    assert q[0] >= 0 and abs(np.linalg.norm(q) - 1.0) < 1e-15
    assert same_rotation(q, wxyz(Rotation.from_rotvec(rotvec)), atol=1e-12)
    np.testing.assert_allclose(quat_to_matrix(q), R, atol=1e-14)
    assert np.array_equal(quat_from_matrix(R[None])[0], q)  # the batch takes the same branch


def test_quat_from_matrix_each_branch_exactly():
    """The four branches on matrices with exact answers: the identity (trace), and half turns about x, y, z."""
    np.testing.assert_array_equal(quat_from_matrix(np.eye(3)), IDENTITY_Q)
    for i in range(3):
        R = -np.eye(3)
        R[i, i] = 1.0
        np.testing.assert_array_equal(quat_from_matrix(R), np.eye(4)[i + 1])
        np.testing.assert_array_equal(quat_from_matrix(np.stack([R, np.eye(3)])), [np.eye(4)[i + 1], IDENTITY_Q])


def test_round_trips(quats):
    canonical = np.where(quats[:, :1] < 0, -quats, quats)
    np.testing.assert_allclose(quat_from_matrix(quat_to_matrix(quats)), canonical, atol=1e-14)
    R = scipy_rot(quats).as_matrix()
    np.testing.assert_allclose(quat_to_matrix(quat_from_matrix(R)), R, atol=1e-14)
    one = np.array([quat_from_matrix(Ri) for Ri in R])
    assert np.array_equal(one, quat_from_matrix(R))


@pytest.mark.parametrize(
    "bad, message",
    [
        (np.eye(4), r"R_AB must have shape \(3, 3\)"),
        (np.ones(3), r"R_AB must have shape \(3, 3\)"),
        (np.full((3, 3), math.nan), "R_AB must be finite"),
        (2.0 * np.eye(3), "R_AB must be rotation matrices"),
        (np.diag([1.0, 1.0, -1.0]), "R_AB must be rotation matrices"),  # a reflection
        (np.zeros((3, 3)), "R_AB must be rotation matrices"),
        (np.stack([np.eye(3), np.diag([-1.0, 1.0, 1.0])]), "R_AB must be rotation matrices"),
    ],
)
def test_quat_from_matrix_bad_input(bad, message):
    with pytest.raises(ValueError, match=message):
        quat_from_matrix(bad)


# --- products, conjugates, composition ----------------------------------------------------------------------------


def test_quat_mul_is_composition(quats):
    a, b = quats[:100], quats[100:]
    q_ref = wxyz(scipy_rot(a) * scipy_rot(b))
    got = quat_mul(a, b)
    assert all(same_rotation(g, r) for g, r in zip(got, q_ref, strict=True))
    np.testing.assert_allclose(quat_to_matrix(got), quat_to_matrix(a) @ quat_to_matrix(b), atol=1e-14)
    assert np.array_equal(np.array([quat_mul(x, y) for x, y in zip(a, b, strict=True)]), got)
    # broadcasting one against many
    np.testing.assert_array_equal(quat_mul(a, b[0]), np.array([quat_mul(x, b[0]) for x in a]))


def test_quat_mul_analytic():
    i, j, k = np.eye(4)[1], np.eye(4)[2], np.eye(4)[3]
    np.testing.assert_array_equal(quat_mul(i, j), k)  # Hamilton: ij = k, ji = -k, i² = -1
    np.testing.assert_array_equal(quat_mul(j, i), -k)
    np.testing.assert_array_equal(quat_mul(i, i), -IDENTITY_Q)
    q = np.array([0.5, 0.5, -0.5, 0.5])
    np.testing.assert_array_equal(quat_mul(IDENTITY_Q, q), q)
    np.testing.assert_array_equal(quat_mul(q, IDENTITY_Q), q)


def test_conjugate_is_the_inverse(quats):
    np.testing.assert_allclose(quat_to_matrix(quat_conjugate(quats)), scipy_rot(quats).inv().as_matrix(), atol=1e-14)
    np.testing.assert_allclose(quat_mul(quats, quat_conjugate(quats)), np.tile(IDENTITY_Q, (len(quats), 1)), atol=1e-15)
    np.testing.assert_array_equal(quat_conjugate([1.0, 2.0, -3.0, 4.0]), [1.0, -2.0, 3.0, -4.0])


@pytest.mark.parametrize("fn", [lambda q: quat_mul(q, IDENTITY_Q), lambda q: quat_mul(IDENTITY_Q, q), quat_conjugate])
@pytest.mark.parametrize(
    "bad, message",
    [
        ([1.0, 0.0], "must have shape"),
        ([math.nan, 0.0, 0.0, 1.0], "finite"),
        ([[math.inf, 0.0, 0.0, 1.0]] * 2, "finite"),
    ],
)
def test_products_bad_input(fn, bad, message):
    with pytest.raises(ValueError, match=message):
        fn(np.asarray(bad))


# --- yaw, vectors, two-vector rotations -----------------------------------------------------------------------------


@pytest.mark.parametrize("yaw", [0.0, 0.3, -2.0, math.pi / 2, 3.1, -3.1, math.pi])
def test_yaw_quaternion_and_yaw_of(yaw):
    q = yaw_quaternion(yaw)
    assert same_rotation(q, wxyz(Rotation.from_euler("z", yaw)), atol=1e-15)
    assert yaw_of(q) == pytest.approx(yaw, abs=1e-12)
    # heading of a tilted body: scipy's intrinsic z-y-x Euler angles
    r = Rotation.from_euler("ZYX", [yaw, 0.4, -0.2])
    assert yaw_of(wxyz(r)) == pytest.approx(r.as_euler("ZYX")[0], abs=1e-12)


def test_yaw_bad_input():
    with pytest.raises(ValueError, match="yaw must be a finite angle"):
        yaw_quaternion(math.nan)
    with pytest.raises(ValueError, match="q_WB must be non-zero"):
        yaw_of([0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="q_WB must be finite"):
        yaw_of([math.nan, 0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match=r"q_WB must have shape \(4,\)"):
        yaw_of([[1.0, 0.0, 0.0, 0.0]])


def test_world_to_body(quats, rng):
    v_W = rng.standard_normal((len(quats), 3))
    ref = scipy_rot(quats).inv().apply(v_W)
    got = np.array([world_to_body(*q, *v) for q, v in zip(quats, v_W, strict=True)])
    np.testing.assert_allclose(got, ref, atol=1e-14)
    with pytest.raises(ValueError, match="world_to_body needs finite numbers"):
        world_to_body(1.0, 0.0, 0.0, 0.0, math.nan, 0.0, 0.0)


def test_cross(rng):
    for a, b in rng.standard_normal((20, 2, 3)):
        np.testing.assert_allclose(cross(a, b), np.cross(a, b), atol=1e-15)
    with pytest.raises(ValueError, match="a must be 3 finite numbers"):
        cross([1.0, 2.0], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="b must be 3 finite numbers"):
        cross([1.0, 2.0, 3.0], [1.0, math.nan, 3.0])


def test_quat_from_two_vectors(rng):
    for u, v in rng.standard_normal((50, 2, 3)):
        u, v = u / np.linalg.norm(u), v / np.linalg.norm(v)
        q = quat_from_two_vectors(u, v)
        r = scipy_rot(q)
        np.testing.assert_allclose(r.apply(u), v, atol=1e-12)
        assert r.magnitude() == pytest.approx(math.acos(np.clip(u @ v, -1, 1)), abs=1e-9)  # the shortest
    for u in (np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.6, 0.8])):  # opposite: a half turn about a normal
        q = quat_from_two_vectors(u, -u)
        np.testing.assert_allclose(scipy_rot(q).apply(u), -u, atol=1e-12)
        assert abs(q[1:] @ u) < 1e-15 and q[0] == 0.0
    np.testing.assert_array_equal(quat_from_two_vectors([0.0, 0.0, 1.0], [0.0, 0.0, 1.0]), IDENTITY_Q)
    with pytest.raises(ValueError, match="u_A must be 3 finite numbers"):
        quat_from_two_vectors([0.0, 1.0], [0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="v_A must be 3 finite numbers"):
        quat_from_two_vectors([0.0, 0.0, 1.0], [math.nan, 0.0, 1.0])


@pytest.mark.parametrize("yaw", [0.0, 0.7, -2.5])
def test_attitude_from_thrust_and_yaw(yaw, rng):
    np.testing.assert_allclose(
        attitude_from_thrust_and_yaw(np.array([0.0, 0.0, 1.0]), yaw),
        Rotation.from_euler("z", yaw).as_matrix(),
        atol=1e-15,
    )
    z = rng.standard_normal(3) + [0.0, 0.0, 3.0]
    z /= np.linalg.norm(z)
    R = attitude_from_thrust_and_yaw(z, yaw)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R[:, 2], z, atol=1e-15)
    # body x lies in the vertical plane through the heading (normal to [-sin yaw, cos yaw, 0]), pointing forward
    assert abs(R[:, 0] @ [-math.sin(yaw), math.cos(yaw), 0.0]) < 1e-14
    assert R[:, 0] @ [math.cos(yaw), math.sin(yaw), 0.0] > 0


# --- unit quaternions and transforms --------------------------------------------------------------------------------


def test_unit_quaternion():
    np.testing.assert_allclose(unit_quaternion([2.0, 0.0, 0.0, 0.0]), IDENTITY_Q)
    np.testing.assert_allclose(unit_quaternion([1.0, 1.0, 1.0, 1.0]), [0.5] * 4)
    with pytest.raises(ValueError, match=r"q_mount must be 4 finite numbers"):
        unit_quaternion([1.0, 0.0, 0.0], "q_mount")
    with pytest.raises(ValueError, match=r"q_mount must be 4 finite numbers"):
        unit_quaternion([1.0, 0.0, math.nan, 0.0], "q_mount")
    with pytest.raises(ValueError, match="q_mount must be a non-zero quaternion"):
        unit_quaternion([0.0, 0.0, 0.0, 0.0], "q_mount")


def _random_transform(rng: np.random.Generator) -> Transform:
    q = rng.standard_normal(4)
    return Transform(tuple(rng.standard_normal(3)), tuple(q / np.linalg.norm(q)))


def test_transform_against_scipy(rng):
    T_AB = _random_transform(rng)
    r = scipy_rot(np.array(T_AB.q))
    np.testing.assert_allclose(T_AB.R, r.as_matrix(), atol=1e-14)
    M = homogeneous(T_AB)
    p_B = rng.standard_normal((10, 3))
    p_A = r.apply(p_B) + T_AB.t
    np.testing.assert_allclose((M[:3, :3] @ p_B.T).T + M[:3, 3], p_A, atol=1e-14)
    np.testing.assert_array_equal(M[3], [0.0, 0.0, 0.0, 1.0])


def test_transform_compose_and_inverse(rng):
    T_AB, T_BC = _random_transform(rng), _random_transform(rng)
    T_AC = T_AB @ T_BC
    np.testing.assert_allclose(homogeneous(T_AC), homogeneous(T_AB) @ homogeneous(T_BC), atol=1e-14)
    np.testing.assert_allclose(homogeneous(T_AB.inverse()), np.linalg.inv(homogeneous(T_AB)), atol=1e-13)
    T_AA = T_AB @ T_AB.inverse()
    np.testing.assert_allclose(T_AA.t, 0.0, atol=1e-14)
    assert same_rotation(np.array(T_AA.q), IDENTITY_Q, atol=1e-15)
    assert Transform() @ T_AB == T_AB


def test_transform_normalises_and_validates():
    T = Transform((1, 2, 3), (2.0, 0.0, 0.0, 0.0))
    assert T.t == (1.0, 2.0, 3.0) and T.q == (1.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match=r"t must be 3 finite numbers \[m\]"):
        Transform((0.0, math.nan, 0.0))
    with pytest.raises(ValueError, match="t must be 3 finite numbers"):
        Transform((0.0, 0.0))
    with pytest.raises(ValueError, match="q must be a non-zero quaternion"):
        Transform(q=(0.0, 0.0, 0.0, 0.0))
    with pytest.raises(TypeError, match="T_AB must be a cufund.geometry.Transform"):
        homogeneous(np.eye(4))


# --- pose trajectories ----------------------------------------------------------------------------------------------


def test_sample_poses_composes_the_mounting(rng):
    T_BS = _random_transform(rng)
    knots = rng.standard_normal((5, 4))

    def pose_fn(t: float) -> tuple[np.ndarray, np.ndarray]:
        return np.array([t, 2 * t, -t]), knots[int(t)] * 3.0  # not unit: normalised by sample_poses

    times = np.arange(5.0)
    p_WS, q_WS = sample_poses(pose_fn, times, T_BS)
    r_WB = scipy_rot(knots)
    r_WS = r_WB * scipy_rot(np.array(T_BS.q))
    np.testing.assert_allclose(p_WS, np.stack([times, 2 * times, -times], 1) + r_WB.apply(T_BS.t), atol=1e-14)
    assert all(same_rotation(a, b) for a, b in zip(q_WS, wxyz(r_WS), strict=True))
    assert np.all(np.sum(q_WS[1:] * q_WS[:-1], axis=1) >= 0)  # signs aligned: interpolation takes the short way
    with pytest.raises(ValueError, match=r"pose_fn\(0.0\) must return p_W as 3 finite numbers"):
        sample_poses(lambda t: ([0.0, math.nan, 0.0], IDENTITY_Q), np.array([0.0]), T_BS)
    with pytest.raises(ValueError, match=r"pose_fn\(0.0\) q_WB must be a non-zero quaternion"):
        sample_poses(lambda t: ([0.0, 0.0, 0.0], [0.0] * 4), np.array([0.0]), T_BS)


def test_interpolate_poses(rng):
    t_k = np.array([0.0, 1.0, 3.0])
    p_k = rng.standard_normal((3, 3))
    r_k = Rotation.from_rotvec([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.5, 0.0, 1.0]])
    q_k = wxyz(r_k)
    q_k[1] = -q_k[1]  # the other sign of the same rotation: interpolation still takes the short way
    t = np.array([-1.0, 0.0, 0.5, 1.0, 2.0, 3.0, 5.0])
    p, R = interpolate_poses(t_k, p_k, q_k, t)
    np.testing.assert_allclose(
        p, [p_k[0], p_k[0], (p_k[0] + p_k[1]) / 2, p_k[1], (p_k[1] + p_k[2]) / 2, p_k[2], p_k[2]], atol=1e-15
    )
    # at the knots, the clamped ends and the midpoints (where normalised lerp and slerp agree): scipy's Slerp
    ref = Slerp(t_k, r_k)(np.clip(t, 0.0, 3.0)).as_matrix()
    np.testing.assert_allclose(R, ref, atol=1e-14)
    p1, R1 = interpolate_poses(t_k[:1], p_k[:1], q_k[:1], t)
    np.testing.assert_array_equal(p1, np.repeat(p_k[:1], len(t), 0))
    np.testing.assert_allclose(R1, np.repeat(np.eye(3)[None], len(t), 0), atol=1e-15)
    with pytest.raises(ValueError, match=r"pose knots must be stamps \(K,\)"):
        interpolate_poses(t_k, p_k[:2], q_k, t)
    with pytest.raises(ValueError, match=r"pose knots must be stamps \(K,\)"):
        interpolate_poses(t_k[:0], p_k[:0], q_k[:0], t)


# --- 0.1's names ----------------------------------------------------------------------------------------------------


def test_duplicate_names_of_0_1_import_with_a_deprecation_warning(quats):
    for old, new in [
        ("quat_multiply", quat_mul),
        ("quat_to_rotation", quat_to_matrix),
        ("rotation_to_quat", quat_from_matrix),
    ]:
        with pytest.warns(DeprecationWarning, match=f"cufund.geometry.{old} is"):
            assert getattr(geometry, old) is new
    with pytest.warns(DeprecationWarning, match="matrix_from_quat is quat_to_matrix"):
        matrix_from_quat = geometry.matrix_from_quat
    np.testing.assert_array_equal(matrix_from_quat(2.0 * quats[0]), quat_to_matrix(quats[0] * 2.0, normalize=True))
    with pytest.raises(AttributeError, match="has no attribute 'nonexistent'"):
        geometry.nonexistent  # noqa: B018


def test_old_module_paths_keep_their_names():
    """In a fresh interpreter: every public name of the three 0.1 modules imports from its old path, warned."""
    code = (
        "import warnings\n"
        "warnings.simplefilter('ignore', DeprecationWarning)\n"
        "from cufund.sensors.pose import (PoseFn, Transform, interpolate_poses, quat_mul, quat_to_matrix,\n"
        "    sample_poses, world_to_body, yaw_quaternion)\n"
        "from cufund.control.rotations import (cross, quat_multiply, quat_conjugate, quat_to_rotation,\n"
        "    rotation_to_quat, quat_from_two_vectors, attitude_from_thrust_and_yaw, yaw_of)\n"
        "from cufund.estimation.frames import (quat_from_matrix, matrix_from_quat, pose3, pose3_parts,\n"
        "    homogeneous, scan_frame)\n"
        "import cufund.geometry as g, cufund.estimation.boundary as b\n"
        "assert quat_multiply is g.quat_mul and rotation_to_quat is g.quat_from_matrix and pose3 is b.pose3\n"
        "assert quat_from_matrix is g.quat_from_matrix and scan_frame is b.scan_frame\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]


def test_euler_zyx_against_scipy():
    """Roll, pitch, yaw as scipy's intrinsic "ZYX" angles (reversed), including near gimbal lock."""
    rng = np.random.default_rng(31)
    qs = rng.normal(size=(500, 4))
    qs /= np.linalg.norm(qs, axis=1, keepdims=True)
    near_lock = np.array([[np.cos(a / 2), 0.0, np.sin(a / 2), 0.0] for a in (np.pi / 2 - 1e-9, -np.pi / 2 + 1e-9)])
    for q in np.vstack([qs, near_lock]):
        roll, pitch, yaw = geometry.euler_zyx(q)
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", "Gimbal lock", UserWarning)  # scipy's, at the two near-lock cases
            ypr = Rotation.from_quat(q[[1, 2, 3, 0]]).as_euler("ZYX")
        # asin loses precision as its argument nears +-1: within sqrt(eps) ~ 1.5e-8 of a half pi
        assert abs(pitch - ypr[1]) < (1e-9 if abs(abs(pitch) - np.pi / 2) > 1e-4 else 3e-8)
        if abs(abs(pitch) - np.pi / 2) > 1e-6:  # away from gimbal lock roll and yaw are defined
            np.testing.assert_allclose([roll, yaw], [ypr[2], ypr[0]], atol=1e-9)
        # the angles rebuild the rotation (also at gimbal lock, where only their sum or difference is defined)
        R = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
        np.testing.assert_allclose(R, geometry.quat_to_matrix(q), atol=1e-7)
    assert geometry.euler_zyx([1, 0, 0, 0]) == (0.0, 0.0, 0.0)
    assert geometry.euler_zyx(geometry.yaw_quaternion(0.5))[2] == geometry.yaw_of(geometry.yaw_quaternion(0.5))
    with pytest.raises(ValueError, match="q_WB"):
        geometry.euler_zyx([0, 0, 0, 0])


def test_quat_from_rotvec_matches_scipy_and_is_first_order_at_zero():
    from scipy.spatial.transform import Rotation

    from cufund.geometry import quat_from_rotvec

    rng = np.random.default_rng(7)
    for phi in rng.normal(size=(20, 3)) * 2.0:
        q = quat_from_rotvec(phi)
        ref = Rotation.from_rotvec(phi).as_quat()[[3, 0, 1, 2]]
        np.testing.assert_allclose(q * np.sign(q[0] * ref[0] or 1.0), ref, atol=1e-12)
    np.testing.assert_allclose(quat_from_rotvec([1e-14, 0.0, -2e-14]), [1.0, 5e-15, 0.0, -1e-14])
    with pytest.raises(ValueError, match="phi"):
        quat_from_rotvec([0.0, np.nan, 0.0])


def test_attitude_from_up_and_yaw_matches_scipy_zyx():
    from scipy.spatial.transform import Rotation

    from cufund.geometry import attitude_from_up_and_yaw

    rng = np.random.default_rng(8)
    for yaw, pitch, roll in rng.uniform([-3, -1.2, -1.2], [3, 1.2, 1.2], (20, 3)):
        R = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
        np.testing.assert_allclose(attitude_from_up_and_yaw(R.T @ [0, 0, 1] * 9.8, yaw), R, atol=1e-12)
    with pytest.raises(ValueError, match="up_B"):
        attitude_from_up_and_yaw([0.0, 0.0, 0.0], 0.0)
