"""Fuzz: the tunnel detector's kernels in cufund._core.perception (DBSCAN, deskew-crop, line support)."""

from __future__ import annotations

import numpy as np
from fuzz_support import Code, arrays, expect_good, fuzz_settings, scalars
from hypothesis import given
from hypothesis import strategies as st

HUGE_POINTS = Code("np.broadcast_to(np.float64([0, 0, 0]), (2**31, 3))")


@fuzz_settings
@given(
    points=st.one_of(arrays([(6, 3), (0, 3), (3,), (4, 2)]), st.just(HUGE_POINTS)),
    eps=st.one_of(st.just(0.5), scalars()),
    min_points=st.one_of(st.just(2), scalars()),
)
def test_dbscan(server, points, eps, min_points):
    outcome, detail = server.run(
        "perception",
        "",
        "result = cufund._core.perception.dbscan(points, eps, min_points)",
        {"points": points, "eps": eps, "min_points": min_points},
        check="result.dtype == np.int64 and (result >= -1).all()",
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(
    which=st.sampled_from(
        [
            "points_L",
            "dt",
            "stride",
            "span",
            "p_WL",
            "R_WL",
            "max_range",
            "z_min",
            "z_max",
            "tall_z",
            "column_cell",
            "tall",
        ]
    ),
    value=st.one_of(arrays([(4, 3), (4,), (3, 3), (3, 3, 3), (0,), (2,)]), scalars()),
)
def test_deskew_crop(server, which, value):
    args = {
        "points_L": np.ones((4, 3), np.float32),
        "dt": np.linspace(0.0, 0.1, 4),
        "stride": 1,
        "span": 0.1,
        "p_WL": np.zeros((3, 3)),
        "R_WL": np.tile(np.eye(3), (3, 1, 1)),
        "max_range": 6.0,
        "z_min": -1.0,
        "z_max": 3.0,
        "tall_z": 2.6,
        "column_cell": 0.1,
        "tall": np.zeros(0, np.int64),
    }
    args[which] = value
    call = (
        "result = cufund._core.perception.deskew_crop(points_L, dt, stride, span, p_WL, R_WL, max_range, z_min, "
        "z_max, tall_z, column_cell, tall)"
    )
    outcome, detail = server.run(
        "perception", "", call, args, check="result[0].shape == result[1].shape and np.isfinite(result[0]).all()"
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(
    along=arrays([(5, 2), (0, 2), (5,), (2, 5)], st.integers(-(2**62), 2**62).map(float)),
    inlier=st.one_of(arrays([(5, 2), (2, 5)]), st.just(np.ones((5, 2), bool))),
)
def test_line_support(server, along, inlier):
    outcome, detail = server.run(
        "perception",
        "",
        "result = cufund._core.perception.line_support(along, inlier)",
        {"along": along, "inlier": inlier},
        check="(result[0] <= result[1]).all() and (result[0] >= 0).all()",
    )
    expect_good(outcome, detail)
