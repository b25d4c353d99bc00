"""cufund.apps.mavlink.frames against independent facts: scipy rotations, PX4's documented NED/FRD conventions
(positive roll = right wing down, positive pitch = nose up, yaw clockwise from north), WGS-84 radii of curvature."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from cufund.apps.mavlink import frames as F
from cufund.core.config import ConfigError
from cufund.sensors.geodesy import GeoPoint, enu_to_lla

R_NED_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
R_FLU_FRD = np.diag([1.0, -1.0, -1.0])


def _scipy(q_wxyz: np.ndarray) -> Rotation:
    return Rotation.from_quat(np.asarray(q_wxyz)[..., [1, 2, 3, 0]])


def _wxyz(r: Rotation) -> np.ndarray:
    return r.as_quat()[..., [3, 0, 1, 2]]


def _px4_euler_deg(q_NED_FRD: np.ndarray) -> np.ndarray:
    """(roll, pitch, yaw) [deg], PX4's intrinsic Z-Y-X (yaw, pitch, roll) Tait-Bryan angles."""
    yaw, pitch, roll = _scipy(q_NED_FRD).as_euler("ZYX", degrees=True)
    return np.array([roll, pitch, yaw])


def test_vector_swaps_are_involutions_and_match_matrices():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(50, 3))
    np.testing.assert_array_equal(F.enu_to_ned(v), v @ R_NED_ENU.T)
    np.testing.assert_array_equal(F.flu_to_frd(v), v @ R_FLU_FRD.T)
    np.testing.assert_array_equal(F.ned_to_enu(F.enu_to_ned(v)), v)
    np.testing.assert_array_equal(F.frd_to_flu(F.flu_to_frd(v)), v)
    np.testing.assert_array_equal(F.enu_to_ned([1.0, 2.0, 3.0]), [2.0, 1.0, -3.0])
    assert F.enu_to_ned(np.zeros((2, 5, 3))).shape == (2, 5, 3)


def test_hover_specific_force_and_yaw_rate_signs():
    # At rest the accelerometer measures +g up in FLU; PX4 expects (0, 0, -g) in FRD.
    np.testing.assert_array_equal(F.flu_to_frd([0.0, 0.0, 9.81]), [0.0, 0.0, -9.81])
    # Yawing left (counter-clockwise seen from above) is +z in FLU and -z (negative yaw rate) in FRD.
    assert F.rates_flu_to_frd([0.0, 0.0, 0.5])[2] == -0.5
    # Rolling right wing down: +x in both.
    assert F.rates_flu_to_frd([0.3, 0.0, 0.0])[0] == 0.3


def test_attitude_against_scipy_composition():
    q_WB = _wxyz(Rotation.random(200, random_state=1))
    q = F.q_enu_flu_to_ned_frd(q_WB)
    R_expected = R_NED_ENU @ _scipy(q_WB).as_matrix() @ R_FLU_FRD
    np.testing.assert_allclose(_scipy(q).as_matrix(), R_expected, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(q, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(F.q_ned_frd_to_enu_flu(q), q_WB, atol=1e-15)


@pytest.mark.parametrize(
    "q_WB, euler_px4",
    [
        # level, nose east: yaw +90 (clockwise from north)
        (_wxyz(Rotation.identity()), (0.0, 0.0, 90.0)),
        # level, nose north (cufund yaw +90 about ENU z): PX4 yaw 0
        (_wxyz(Rotation.from_euler("z", 90, degrees=True)), (0.0, 0.0, 0.0)),
        # nose west: PX4 yaw -90
        (_wxyz(Rotation.from_euler("z", 180, degrees=True)), (0.0, 0.0, -90.0)),
        # nose north, nose up 10 deg (about FLU +y = left, a negative angle): PX4 pitch +10
        (_wxyz(Rotation.from_euler("ZY", [90, -10], degrees=True)), (0.0, 10.0, 0.0)),
        # nose north, right wing down 20 deg (about FLU +x): PX4 roll +20
        (_wxyz(Rotation.from_euler("ZX", [90, 20], degrees=True)), (20.0, 0.0, 0.0)),
    ],
)
def test_attitude_matches_px4_euler_conventions(q_WB, euler_px4):
    np.testing.assert_allclose(_px4_euler_deg(F.q_enu_flu_to_ned_frd(q_WB)), euler_px4, atol=1e-9)


def test_body_vector_rotated_consistently():
    # A body vector taken to world must agree whichever convention does the rotating.
    rng = np.random.default_rng(2)
    q_WB = _wxyz(Rotation.random(20, random_state=3))
    v_B = rng.normal(size=(20, 3))
    v_W_cufund = _scipy(q_WB).apply(v_B)
    v_N_px4 = _scipy(F.q_enu_flu_to_ned_frd(q_WB)).apply(F.flu_to_frd(v_B))
    np.testing.assert_allclose(F.enu_to_ned(v_W_cufund), v_N_px4, atol=1e-12)


def test_geodetic_small_offsets_match_wgs84_radii_of_curvature():
    o = F.GeodeticOrigin(0.0, 0.0, 0.0)
    meridional = 6378137.0 * (1.0 - 0.00669437999014)  # WGS-84 meridional radius at the equator: a(1 - e^2)
    lla = o.ned_to_lla(np.array([[1000.0, 0.0, 0.0], [0.0, 1000.0, 0.0], [0.0, 0.0, -25.0]]))
    np.testing.assert_allclose(lla[0, :2], [np.degrees(1000.0 / meridional), 0.0], atol=2e-9)
    np.testing.assert_allclose(lla[1, :2], [0.0, np.degrees(1000.0 / 6378137.0)], atol=2e-9)
    np.testing.assert_allclose(lla[2], [0.0, 0.0, 25.0], atol=1e-6)  # NED z = -25 is 25 m up


def test_geodetic_round_trip_and_same_projection_as_gps_sensor():
    o = F.GeodeticOrigin(47.397742, 8.545594, 488.0)  # PX4's default SITL home (Zurich)
    rng = np.random.default_rng(4)
    p_W = rng.uniform(-2000.0, 2000.0, size=(100, 3))
    lla = o.enu_to_lla(p_W)
    np.testing.assert_array_equal(lla, enu_to_lla(p_W, GeoPoint(47.397742, 8.545594, 488.0)))
    np.testing.assert_allclose(o.lla_to_enu(lla), p_W, atol=1e-6)
    np.testing.assert_allclose(o.lla_to_ned(o.ned_to_lla(p_W)), p_W, atol=1e-6)
    assert F.GeodeticOrigin.from_geo_point(o.geo_point) == o


def test_geodetic_origin_validates():
    with pytest.raises(ConfigError, match="latitude_deg"):
        F.GeodeticOrigin(91.0, 0.0)
    with pytest.raises(ConfigError, match="longitude_deg"):
        F.GeodeticOrigin(0.0, float("nan"))


def test_integer_encodings():
    assert F.deg_to_e7(47.3977419) == 473977419
    assert F.deg_to_e7(-122.0) == -1220000000
    np.testing.assert_array_equal(F.deg_to_e7(np.array([1.0, -1.0])), [10_000_000, -10_000_000])
    assert F.e7_to_deg(473977419) == pytest.approx(47.3977419, abs=1e-12)
    assert F.m_to_mm(488.1234) == 488123 and F.mm_to_m(488123) == 488.123
    assert F.m_s_to_cm_s(-1.234) == -123 and F.m_s_to_cm_s(1e6) == 32767 and F.m_s_to_cm_s(-1e6) == -32767
    assert F.cm_s_to_m_s(150) == 1.5
    assert F.m_s2_to_mg(F.STANDARD_GRAVITY) == 1000 and F.m_s2_to_mg(-9.81) == -1000
    assert F.mg_to_m_s2(1000) == pytest.approx(F.STANDARD_GRAVITY)
    assert F.m_to_cm_u16(0.3) == 30 and F.m_to_cm_u16(1e9) == 65534 and F.m_to_cm_u16(-1.0) == 0
    assert isinstance(F.deg_to_e7(1.0), int)


def test_course_over_ground():
    v = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [1.0, -1.0, 0.0], [0.0, 0.0, 3.0]])
    np.testing.assert_array_equal(F.course_cdeg(v), [0, 9000, 18000, 31500, F.UINT16_UNKNOWN])
    assert F.course_cdeg([0.05, 0.0, 0.0], min_speed_m_s=0.1) == F.UINT16_UNKNOWN


def test_bad_input_raises():
    with pytest.raises(ValueError, match=r"v_ENU must have shape \(\.\.\., 3\)"):
        F.enu_to_ned(np.zeros(4))
    with pytest.raises(ValueError, match="q_WB"):
        F.q_enu_flu_to_ned_frd(np.zeros(3))
    with pytest.raises(ValueError, match="finite"):
        F.deg_to_e7(float("nan"))


def test_yaw_conversions_match_the_attitude_conversion():
    np.testing.assert_allclose(
        F.yaw_enu_to_ned(np.array([0.0, np.pi / 2, np.pi, -np.pi / 2])),
        [np.pi / 2, 0.0, -np.pi / 2, np.pi - 2 * np.pi],
        atol=1e-12,
    )  # east, north, west, south
    yaw = np.random.default_rng(5).uniform(-np.pi, np.pi, 50)
    q_WB = _wxyz(Rotation.from_euler("z", yaw[:, None]))
    yaw_px4 = _scipy(F.q_enu_flu_to_ned_frd(q_WB)).as_euler("ZYX")[:, 0]
    np.testing.assert_allclose(np.cos(F.yaw_enu_to_ned(yaw) - yaw_px4), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.cos(F.yaw_ned_to_enu(F.yaw_enu_to_ned(yaw)) - yaw), 1.0, atol=1e-12)
    assert isinstance(F.yaw_enu_to_ned(0.3), float)


def test_vector_conversions_keep_exact_values_and_do_not_alias():
    v = np.array([[0.0, -0.0, 1e-300], [np.inf, -2.5, 7.0]])
    out = F.enu_to_ned(v)
    np.testing.assert_array_equal(out, [[-0.0, 0.0, -1e-300], [-2.5, np.inf, -7.0]])
    out[0, 0] = 99.0
    assert v[0, 1] == 0.0 and F.flu_to_frd(v) is not v
