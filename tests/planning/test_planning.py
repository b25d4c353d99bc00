"""Path search on the ESDF: certified clearance, grid A*, OMPL — checked against Open3D's exact distance
to the world's triangles (independent of the ESDF)."""

from __future__ import annotations

import numpy as np
import pytest

from cufund.core.config import ConfigError
from cufund.planning import (
    ClearanceQuery,
    GridPathSearch,
    GridPathSearchParams,
    OmplPathParams,
    OmplPathPlanner,
    esdf_from_world,
)
from cufund.worlds import World
from cufund.worlds.builtin import forest

o3d = pytest.importorskip("open3d")

RES = 0.1
BOUNDS = np.array([[-9.0, -9.0, 0.0], [9.0, 9.0, 2.5]])  # the whole forest: nothing outside the map is nearer


def _forest() -> World:
    return forest(seed=3, n_trees=60, size=16.0, clearing=1.0)


def _truth(world: World):
    scene = o3d.t.geometry.RaycastingScene()
    for o in world.objects:
        scene.add_triangles(o.vertices.astype(np.float32), o.triangles.astype(np.uint32))
    return lambda p: scene.compute_distance(np.asarray(p, np.float32).reshape(-1, 3)).numpy().astype(float)


@pytest.fixture(scope="module")
def setting():
    world = _forest()
    esdf = esdf_from_world(world, RES, BOUNDS, nthreads=1)
    return world, ClearanceQuery(esdf), _truth(world)


def _dense(path: np.ndarray, step: float = 0.01) -> np.ndarray:
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:], strict=True):
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / step)) + 1)
        out.append(a + np.linspace(0.0, 1.0, n)[:, None] * (b - a))
    return np.vstack(out)


def test_clearance_is_a_tight_lower_bound_on_the_distance_to_the_triangles(setting):
    _, q, truth = setting
    rng = np.random.default_rng(0)
    p = rng.uniform(BOUNDS[0], BOUNDS[1], size=(4000, 3))
    c, d = q.clearance(p), truth(p)
    assert np.all(c <= d + 1e-5)
    # Surfaces anywhere in their voxels: at most 4 half-diagonals of slack (2 sqrt(3) h).
    assert np.all(c >= d - 2.0 * np.sqrt(3.0) * RES - 1e-5)
    assert np.median(d - c) < 1.5 * RES  # typical slack (measured 1.42 h): the half diagonal and the voxelisation
    # The scalar fast path is the same function.
    assert [q.clearance_xyz(*x) for x in p[:50]] == c[:50].tolist()
    assert q.clearance(p[7]) == c[7]


def test_clearance_outside_the_map_is_minus_infinity_and_inputs_are_checked(setting):
    _, q, _ = setting
    assert q.clearance([20.0, 0.0, 1.0]) == -np.inf
    assert q.clearance_xyz(float("nan"), 0.0, 1.0) == -np.inf
    assert not q.segment_free([0.0, 0.0, 1.0], [20.0, 0.0, 1.0], 0.1)
    with pytest.raises(ValueError, match="radius must be finite and >= 0"):
        q.segment_free([0.0, 0.0, 1.0], [1.0, 0.0, 1.0], -0.1)
    with pytest.raises(ValueError, match=r"p1_W must be 3 finite numbers"):
        q.segment_free([0.0, 0.0, 1.0], [1.0, 0.0], 0.1)
    with pytest.raises(ValueError, match=r"points_W must have shape \(N, 3\), got \(4, 2\)"):
        q.clearance(np.zeros((4, 2)))
    with pytest.raises(TypeError, match="esdf_map must be a cufund.mapping.EsdfMap"):
        ClearanceQuery(np.zeros((3, 3, 3)))


def test_scalar_fast_path_is_the_bound_query_with_checked_arguments(setting):
    _, q, _ = setting
    rng = np.random.default_rng(3)
    p = rng.uniform(BOUNDS[0], BOUNDS[1], size=(40, 3))
    # The plain builtins agree with the pybind11 methods (ints, numpy scalars and keywords too).
    assert [q.clearance_xyz(*x) for x in p] == [q._core.clearance(*x) for x in p]
    assert q.clearance_xyz(1, np.float32(0.5), np.float64(1.0)) == q._core.clearance(1.0, 0.5, 1.0)
    assert q.clearance_xyz(x=1.0, y=0.5, z=1.0) == q._core.clearance(1.0, 0.5, 1.0)
    for a, b in zip(p[:-1], p[1:], strict=True):
        assert q.segment_free_xyz(*a, *b, 0.2) is q._core.segment_free(*a, *b, 0.2)
    with pytest.raises(TypeError, match="y must be a real number"):
        q.clearance_xyz(1.0, "2", 3.0)
    with pytest.raises(TypeError, match="z must be a real number"):
        q.clearance_xyz(1.0, 2.0, True)
    with pytest.raises(TypeError):
        q.clearance_xyz(1.0, 2.0)
    with pytest.raises(ValueError, match="radius must be finite and >= 0"):
        q.segment_free_xyz(0.0, 0.0, 1.0, 1.0, 0.0, 1.0, float("nan"))
    # A builtin keeps its query alive.
    f = ClearanceQuery.from_distances(np.full((4, 4, 4), 0.5), [0.0, 0.0, 0.0], 0.1).clearance_xyz
    assert f(0.15, 0.15, 0.15) == pytest.approx(0.5 - 0.5 * np.sqrt(3.0) * 0.1)  # at a voxel centre


def test_segment_free_is_certified_against_the_triangles(setting):
    _, q, truth = setting
    rng = np.random.default_rng(1)
    radius, n_free = 0.2, 0
    for _ in range(300):
        a = rng.uniform(BOUNDS[0] + 0.5, BOUNDS[1] - 0.5)
        b = a + rng.normal(size=3) * 1.5
        if q.segment_free(a, b, radius):
            n_free += 1
            assert truth(_dense(np.stack([a, b]))).min() >= radius - 1e-5
    assert n_free > 50


def _check_path(result, q, truth, start, goal, radius):
    assert result.found, result.status
    path = result.path_W
    np.testing.assert_array_equal(path[0], start)
    np.testing.assert_array_equal(path[-1], goal)
    assert result.length == pytest.approx(np.sum(np.linalg.norm(np.diff(path, axis=0), axis=1)))
    assert result.length >= np.linalg.norm(np.asarray(goal) - start)
    assert truth(_dense(path)).min() >= radius - 1e-5  # every state and every edge clears the radius
    assert q.path_free(path, radius).all()


START, GOAL = np.array([-7.5, -1.0, 1.2]), np.array([7.5, -0.4, 1.0])


def test_grid_astar_path_clears_the_triangles_and_is_deterministic(setting):
    _, q, truth = setting
    params = GridPathSearchParams(radius=0.3)
    a = GridPathSearch(params).plan(q, START, GOAL)
    _check_path(a, q, truth, START, GOAL, 0.3)
    assert len(a.path_W) > 2  # the trees are in the way
    b = GridPathSearch(params).plan(q, START, GOAL)
    np.testing.assert_array_equal(a.path_W, b.path_W)
    assert a.expansions == b.expansions
    optimal = GridPathSearch(GridPathSearchParams(radius=0.3, heuristic_weight=1.0)).plan(q, START, GOAL)
    _check_path(optimal, q, truth, START, GOAL, 0.3)
    assert optimal.expansions > a.expansions  # the weighted search (default 1.2) expands fewer nodes
    assert a.length <= 1.5 * optimal.length


def test_grid_astar_statuses(setting):
    world, q, _ = setting
    tree = next(o for o in world.objects if o.label == "tree")
    inside_tree = tree.vertices.mean(axis=0)
    inside_tree[2] = 1.0
    s = GridPathSearch(GridPathSearchParams(radius=0.3))
    assert s.plan(q, inside_tree, GOAL).status == "start_blocked"
    assert s.plan(q, START, inside_tree).status == "goal_blocked"
    assert s.plan(q, START, [50.0, 0.0, 1.0]).status == "goal_blocked"
    assert s.plan(q, START, [START[0], START[1], 0.1]).status == "goal_blocked"  # the ground
    few = GridPathSearch(GridPathSearchParams(radius=0.3, max_expansions=5)).plan(q, START, GOAL)
    assert few.status == "expansion_limit" and few.path_W.shape == (0, 3)
    with pytest.raises(ConfigError, match="radius must be a finite number >= 0"):
        GridPathSearchParams(radius=-1.0)
    with pytest.raises(ConfigError, match="heuristic_weight must be a finite number >= 1"):
        GridPathSearchParams(heuristic_weight=0.5)
    with pytest.raises(ConfigError, match="max_expansions must be an integer >= 1"):
        GridPathSearchParams(max_expansions=0)
    with pytest.raises(ValueError, match="goal_W must be 3 finite numbers"):
        s.plan(q, START, [1.0, float("inf"), 1.0])


def test_ompl_path_clears_the_triangles_and_improves_on_the_first_solution(setting):
    _, q, truth = setting
    first = OmplPathPlanner(OmplPathParams(radius=0.3, time_limit=2.0, simplify=False)).plan(q, START, GOAL)
    _check_path(first, q, truth, START, GOAL, 0.3)
    best = OmplPathPlanner(OmplPathParams(radius=0.3, time_limit=2.0, improve_time=0.5)).plan(q, START, GOAL)
    _check_path(best, q, truth, START, GOAL, 0.3)
    astar = GridPathSearch(GridPathSearchParams(radius=0.3)).plan(q, START, GOAL)
    assert best.length <= 1.1 * astar.length  # simplified, optimised: close to the grid optimum
    bit = OmplPathPlanner(OmplPathParams(radius=0.3, time_limit=2.0, improve_time=0.3, optimizer="bit_star"))
    _check_path(bit.plan(q, START, GOAL), q, truth, START, GOAL, 0.3)
    assert OmplPathPlanner(OmplPathParams(radius=0.3)).plan(q, START, [50.0, 0.0, 1.0]).status == "goal_blocked"
    with pytest.raises(ConfigError, match="optimizer must be one of"):
        OmplPathParams(optimizer="prm")


def test_esdf_from_world_marks_only_voxels_touching_triangles(setting):
    world, q, truth = setting
    esdf = q.esdf_map
    occ = np.argwhere(esdf.occupied())
    centres = esdf.params.origin_W + (occ + 0.5) * RES
    # An occupied voxel touches a triangle: its centre is within half a voxel diagonal of one.
    assert truth(centres).max() <= 0.5 * np.sqrt(3.0) * RES + 1e-5
    with pytest.raises(ValueError, match=r"bounds_W must be finite \[min, max\] corners"):
        esdf_from_world(world, RES, [[0, 0, 0], [0, 1, 1]])


def test_min_snap_through_a_forest_path_keeps_clearance(setting):
    from cufund.planning import MinSnapPlanner, MinSnapPlannerParams

    _, q, truth = setting
    path = GridPathSearch(GridPathSearchParams(radius=0.25)).plan(q, START, GOAL)
    assert path.found
    loose = MinSnapPlanner(MinSnapPlannerParams(v_max=2.0, a_max=3.0)).plan(path.path_W, query=q)
    res = MinSnapPlanner(MinSnapPlannerParams(v_max=2.0, a_max=3.0, radius=0.2)).plan(path.path_W, query=q)
    assert res.status == "ok" and res.inserted > 0
    tr = res.trajectory
    p = tr.sample(np.linspace(tr.t_knots[0], tr.t_end, 20001)).p_W
    assert truth(p).min() >= 0.2 - 1e-5
    assert res.min_clearance >= 0.2
    lt = loose.trajectory
    assert truth(lt.sample(np.linspace(lt.t_knots[0], lt.t_end, 20001)).p_W).min() < 0.2  # the check was needed
    assert res.feasibility.peak_speed <= 2.0 * 1.01


def test_static_field_from_the_world_equals_the_live_map(setting):
    from cufund.planning import clearance_from_world

    world, q, _ = setting
    static = clearance_from_world(world, RES, BOUNDS, nthreads=1)
    np.testing.assert_array_equal(static.bounds_W, q.bounds_W)
    p = np.random.default_rng(5).uniform(BOUNDS[0] - 0.2, BOUNDS[1] + 0.2, size=(2000, 3))
    np.testing.assert_allclose(static.clearance(p), q.clearance(p), rtol=0, atol=1e-12)
    assert static.esdf_map is None
    with pytest.raises(ValueError, match=r"distances must be a 3-D array"):
        ClearanceQuery.from_distances(np.zeros((4, 4)), [0, 0, 0], 0.1)


def test_binding_array_arguments_get_clear_errors():
    """Wrong dtypes, shapes and objects numpy cannot convert raise a ValueError naming the argument (the planning
    bindings read arrays through the checked helpers of pybind_common.h, not array::ensure, which dropped the
    conversion error and cast float triangles to int silently)."""
    from cufund import _core

    pl = _core.planning
    cq = pl.ClearanceQuery(np.zeros(3), 0.1, np.ones((4, 4, 4)))
    with pytest.raises(ValueError, match="points_W must be an array, got list"):
        cq.clearance_many([[0, 0, 0], [1, 2]])
    with pytest.raises(ValueError, match="points_W must have a real numeric dtype .* got complex128"):
        cq.clearance_many(np.zeros((2, 3), complex))
    with pytest.raises(ValueError, match=r"path_W must have shape \(K, 3\), got \(\)"):
        cq.segments_free(object(), 0.1)
    with pytest.raises(ValueError, match=r"distances must be a 3-D array .* got \(2,\)"):
        pl.ClearanceQuery(np.zeros(3), 0.1, [1.0, 2.0])
    with pytest.raises(ValueError, match="distances must be an array, got list"):
        pl.ClearanceQuery(np.zeros(3), 0.1, [[[1.0]], [[1.0, 2.0]]])
    with pytest.raises(ValueError, match=r"values must have shape \(K, d\) with K >= 2, got \(1, 3\)"):
        pl.min_derivative_spline(np.zeros((1, 3)), np.ones(0), 4)
    with pytest.raises(ValueError, match="values must be an array, got list"):
        pl.snap_cost_and_gradient([[0, 0, 0], [1, 1]], [1.0])
    verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    with pytest.raises(ValueError, match="triangles must have an integer dtype, got float64"):
        pl.voxelize_triangles(np.zeros(3), (10, 10, 10), 0.1, verts, np.array([[0.0, 1.0, 2.0]]))
    with pytest.raises(ValueError, match=r"triangles must have shape \(T, 3\), got \(3,\)"):
        pl.voxelize_triangles(np.zeros(3), (10, 10, 10), 0.1, verts, np.array([0, 1, 2]))
    assert len(pl.voxelize_triangles(np.zeros(3), (10, 10, 10), 0.1, verts, np.array([[0, 1, 2]], np.uint8))) > 0
