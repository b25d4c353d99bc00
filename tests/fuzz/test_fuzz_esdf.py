"""Fuzz: ESDF map parameters, scans, queries, pickling; the standalone EDT."""

from __future__ import annotations

from fuzz_support import arrays, expect_good, floats_any, fuzz_settings, scalars
from hypothesis import given
from hypothesis import strategies as st

MAP = """
m = cufund.mapping.EsdfMap(cufund.mapping.EsdfMapParams(resolution=0.1, size=(2.0, 2.0, 1.0), origin_W=(-1.0, -1.0, 0.0)))
m.set_occupied(np.array([[10, 10, 5]]))
"""


@fuzz_settings
@given(
    field=st.sampled_from(
        [
            "resolution",
            "size",
            "origin_W",
            "log_odds_hit",
            "log_odds_miss",
            "log_odds_min",
            "log_odds_max",
            "log_odds_occupied",
            "max_range",
            "signed",
            "nthreads",
        ]
    ),
    value=st.one_of(
        scalars(),
        arrays([(3,), (2,)]),
        st.sampled_from([5e-324, 1e-300, 1e-6, 1e6]),
        st.just((1e5, 1e5, 1e5)),
        st.just((1e-3, 1e-3, 1e-3)),
    ),
)
def test_map_params(server, field, value):
    code = """
kw = {"resolution": 0.1, "size": (2.0, 2.0, 1.0)}
kw[field] = value
m = cufund.mapping.EsdfMap(cufund.mapping.EsdfMapParams(**kw))
m.insert_scan(np.array([[0.5, 0.5, 0.5]]), np.array([0.0, 0.0, 0.1]))
result = m.distance(np.array([0.2, 0.3, 0.4]))
"""
    outcome, detail = server.run("esdf", "", code, {"field": field, "value": value}, check="not np.isnan(result)")
    expect_good(outcome, detail)


@fuzz_settings
@given(points=arrays([(5, 3), (0, 3), (3,), (4, 2)], st.floats(-50, 50) | floats_any()), origin=arrays([(3,)]))
def test_insert_scan(server, points, origin):
    outcome, detail = server.run(
        "esdf",
        MAP,
        "m.insert_scan(points, origin)\nresult = m.distances()",
        {"points": points, "origin": origin},
        check="not np.isnan(result).any()",
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(points=arrays([(5, 3), (3,), (0, 3), (2, 4)], st.floats(-50, 50) | floats_any()), grad=st.booleans())
def test_distance_queries(server, points, grad):
    call = "result = m.distance_and_gradient(points)[0] if grad else m.distance(points)"
    outcome, detail = server.run(
        "esdf", MAP, call, {"points": points, "grad": grad}, check="not np.isnan(np.asarray(result)).any()"
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(ijk=arrays([(2, 3), (1, 3), (3,)], st.integers(-3, 40).map(float)), occupied=st.one_of(st.booleans(), scalars()))
def test_set_occupied(server, ijk, occupied):
    outcome, detail = server.run(
        "esdf",
        MAP,
        "m.set_occupied(ijk, occupied)\nresult = m.distances()",
        {"ijk": ijk, "occupied": occupied},
        check="not np.isnan(result).any()",
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(
    occupied=arrays([(4, 4), (3, 3, 3), (5,), (0, 2)], st.integers(0, 1).map(float)),
    voxel_size=st.one_of(floats_any(), arrays([(2,), (3,), (1,)])),
)
def test_edt(server, occupied, voxel_size):
    outcome, detail = server.run(
        "esdf",
        "",
        "result = cufund.mapping.edt(occupied, voxel_size)",
        {"occupied": occupied, "voxel_size": voxel_size},
        check="not np.isnan(result).any()",
    )
    expect_good(outcome, detail)


@fuzz_settings
@given(scan=arrays([(20, 3)], st.floats(-1.5, 1.5)))
def test_pickle_round_trip(server, scan):
    code = """
import pickle
m.insert_scan(scan, np.array([0.0, 0.0, 0.5]))
c = pickle.loads(pickle.dumps(m))
result = (c.distances().tobytes() == m.distances().tobytes()) and np.array_equal(c.log_odds(), m.log_odds())
"""
    outcome, detail = server.run("esdf", MAP, code, {"scan": scan}, check="result is True")
    expect_good(outcome, detail)
