"""Area coverage split between vehicles (cufund.missions.coverage), checked with shapely: the cells tile the polygon
(union equal to it, no overlap), the lanes' footprint covers a rectangle, the paths are boustrophedon and balanced,
and the rectangle's shares equal the hand-computed ones."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from cufund.missions.coverage import plan_coverage

shapely = pytest.importorskip("shapely")
from shapely.geometry import LineString, Point  # noqa: E402
from shapely.geometry import Polygon as SPolygon  # noqa: E402

RECT = [(0.0, 0.0), (30.0, 0.0), (30.0, 20.0), (0.0, 20.0)]
PENTAGON = [(0.0, 0.0), (14.0, -2.0), (20.0, 9.0), (8.0, 17.0), (-3.0, 8.0)]
L_SHAPE = [(0.0, 0.0), (12.0, 0.0), (12.0, 4.0), (4.0, 4.0), (4.0, 12.0), (0.0, 12.0)]
HOMES3 = {"uav1": (0.0, -3.0, 0.0), "uav2": (15.0, -3.0, 0.0), "uav3": (30.0, -3.0, 0.0)}


@pytest.mark.parametrize("polygon", [RECT, PENTAGON, L_SHAPE])
@pytest.mark.parametrize("n", [1, 2, 3])
def test_cells_cover_the_polygon_without_overlap(polygon, n):
    homes = dict(itertools.islice(HOMES3.items(), n))
    cells = plan_coverage(polygon, homes, spacing=1.5, altitude=5.0)
    area = SPolygon(polygon)
    shapes = [SPolygon(c.polygon).buffer(0) for c in cells.values()]
    union = shapely.union_all(shapes)
    assert union.symmetric_difference(area).area < 1e-6
    assert sum(s.area for s in shapes) == pytest.approx(area.area, abs=1e-6)
    for a, b in itertools.combinations(shapes, 2):
        assert a.intersection(b).area < 1e-9
    for name, c in cells.items():
        path = np.asarray(c.path)
        assert np.all(path[:, 2] == 5.0)
        cell = SPolygon(c.polygon).buffer(1e-6)
        assert all(cell.contains(Point(x, y)) for x, y, _ in path), name  # each vehicle stays in its own cell


def test_the_lanes_footprint_covers_the_rectangle():
    spacing = 2.5
    cells = plan_coverage(RECT, HOMES3, spacing=spacing, altitude=5.0)
    paths = [LineString(np.asarray(c.path)[:, :2]) for c in cells.values()]
    xs, ys = np.meshgrid(np.linspace(0, 30, 61), np.linspace(0, 20, 41))
    for x, y in zip(xs.ravel(), ys.ravel(), strict=True):
        assert min(p.distance(Point(x, y)) for p in paths) <= spacing / 2 + 1e-9, (x, y)


def test_the_rectangle_is_split_into_equal_boustrophedon_shares():
    cells = plan_coverage(RECT, HOMES3, spacing=2.0, altitude=10.0)
    # lanes along y (20 m) 2 m apart: 15 lanes, 5 a vehicle: 5 x 20 m + 4 x 2 m = 108 m each (along x: 10 lanes of
    # 30 m, 4 + 3 + 3, the longest share 4 x 30 + 3 x 2 = 126 m)
    assert [c.lanes for c in cells.values()] == [5, 5, 5]
    for c in cells.values():
        assert c.length == pytest.approx(108.0)
        path = np.asarray(c.path)
        legs = np.diff(path[:, :2], axis=0)
        lanes = legs[0::2]
        assert np.allclose(np.abs(lanes[:, 1]), 20.0) and np.allclose(lanes[:, 0], 0.0)  # along y, full length
        assert np.all(np.sign(lanes[1:, 1]) == -np.sign(lanes[:-1, 1]))  # back and forth
        assert np.allclose(np.abs(legs[1::2, 0]), 2.0)  # one spacing between lanes
    # each vehicle gets the cell in front of it and starts at its nearest corner
    xs = {n: np.mean(np.asarray(c.path)[:, 0]) for n, c in cells.items()}
    assert xs["uav1"] < xs["uav2"] < xs["uav3"]
    for name, c in cells.items():
        path = np.asarray(c.path)[:, :2]
        ends = path[[0, 1, -2, -1]]  # the first and the last lane's ends: where a boustrophedon can start
        home = np.asarray(HOMES3[name][:2])
        assert np.linalg.norm(path[0] - home) == pytest.approx(np.min(np.linalg.norm(ends - home, axis=1)))
        assert path[0][1] == 0.0  # the south side, facing the homes


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="intersects itself"):
        plan_coverage([(0, 0), (10, 10), (10, 0), (0, 10)], {"a": (0, 0)}, 1.0, 5.0)
    with pytest.raises(ValueError, match="spacing"):
        plan_coverage(RECT, {"a": (0, 0)}, 0.0, 5.0)
    with pytest.raises(ValueError, match="too narrow"):
        plan_coverage([(0, 0), (1, 0), (1, 1), (0, 1)], HOMES3, 2.0, 5.0)
    with pytest.raises(ValueError, match="vertices"):
        plan_coverage([(0, 0), (1, 0)], {"a": (0, 0)}, 1.0, 5.0)
