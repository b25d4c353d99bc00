"""Global planning benchmark (issue 13): seeded forests and tunnel courses.

For each layout: the deterministic grid A* (the default global planner) and OMPL's RRTConnect (first
solution, simplified) against an InformedRRT* reference given `--ref-time` seconds. Prints the success
rate (goal reached and, checked independently with Open3D's distance to the world's triangles, never
closer than the radius), path length over the reference's, and planning time median / p99.
Targets (2 cores): success >= 99 % in forests, 100 % in tunnels; length <= 1.05 x reference; global
plan <= 20 ms median. `--local N`: the B-spline local replanner flies N forests by receding horizon at
10 Hz, reporting its success and per-replan time (targets: <= 5 ms median, <= 20 ms p99). `--local-tunnels N`:
the same through N tunnel courses (entry, each frame's centre with a stop, exit; radius 0.15 m on a 2.5 cm ESDF).
Wall and CPU time per replan are printed with the load average: on a loaded machine the wall figure includes
preemption.

Everything above is a planner-only figure: KNOWN MAP, PERFECT TRACKING. The planners get the true world's ESDF
(every trunk, also those no sensor has seen), the tunnels' true frame centres, and the flown curve is the planned
one. No figure of these modes says what a vehicle achieves. `--online N` does: it runs the ``forest_global``
scenario on N forest layouts (the ``global`` planner searching the ESDF built online from a simulated Mid-360,
guiding the local replanner, the vehicle flown by the controllers on the LiDAR-inertial odometry) and prints
success (goal reached, never closer than the radius to a true trunk), time to the goal, flown length and the
online global planner's first-plan and replan figures.

Run: `.venv/bin/python benchmarks/bench_planning.py [--forests 200] [--tunnels 200] [--ref-time 5]`
(the issue's figures: about 20 min for the forests, 100 min for the tunnels' 6 legs each at 5 s; `--split-ref`
shares the 5 s among a tunnel's legs). `--forests 20 --tunnels 20 --ref-time 1` takes about 1 min.
`--scalar`: the per-call cost of the scalar clearance query. `--online 5` takes about a minute per layout.
"""

from __future__ import annotations

import argparse
import math
import os
import time
import timeit

import numpy as np
import open3d as o3d

from cufund.missions.tunnel_course import tunnel_course_layout
from cufund.planning import (
    BsplineLocalPlanner,
    GlobalPlanner,
    GlobalPlannerParams,
    GridPathSearch,
    GridPathSearchParams,
    LocalPlannerParams,
    OmplPathParams,
    OmplPathPlanner,
    clearance_from_world,
    esdf_from_world,
)
from cufund.worlds.builtin import forest

RADIUS_FOREST = 0.3
RES_FOREST = 0.1


def truth_distance(world):
    scene = o3d.t.geometry.RaycastingScene()
    for o in world.objects:
        scene.add_triangles(o.vertices.astype(np.float32), o.triangles.astype(np.uint32))
    return lambda p: scene.compute_distance(np.asarray(p, np.float32).reshape(-1, 3)).numpy()


def dense(path, step=0.01):
    return np.vstack(
        [
            a + np.linspace(0, 1, max(2, int(np.linalg.norm(b - a) / step) + 1))[:, None] * (b - a)
            for a, b in zip(path[:-1], path[1:], strict=True)
        ]
    )


def safe(result, truth, radius):
    return result.found and float(truth(dense(result.path_W)).min()) >= radius - 1e-5


def forest_case(seed):
    """A 40 m forest at 0.15 trees/m^2; start and goal 30 m apart at 1.5 m height, nudged off trunks."""
    world = forest(seed=seed, n_trees=240, size=40.0, clearing=0.0)
    q = clearance_from_world(world, RES_FOREST, [[-17.0, -8.0, 0.0], [17.0, 8.0, 3.0]])
    ends = []
    for x in (-15.0, 15.0):
        for y in np.arange(0.0, 4.0, 0.1):
            p = next(
                (np.array([x, s * y, 1.5]) for s in (1, -1) if q.clearance([x, s * y, 1.5]) >= RADIUS_FOREST + 0.2),
                None,
            )
            if p is not None:
                ends.append(p)
                break
    return world, q, ends[0], ends[1], RADIUS_FOREST


def run(cases, ref_time, label, split=False):
    """``split``: the reference's ``ref_time`` is per layout, shared equally by its legs (else per leg)."""
    astar = dict(ok=0, t=[], ratio=[])
    rrtc = dict(ok=0, t=[], ratio=[])
    n = 0
    seeds = []
    grid = None  # one planner for all layouts: its search buffers are reused while the grid shape stays
    for seed, (world, q, legs, radius) in cases:
        n += 1
        seeds.append(seed)
        truth = truth_distance(world)
        if grid is None or grid.params.radius != radius:
            grid = GridPathSearch(GridPathSearchParams(radius=radius))
        first = OmplPathPlanner(OmplPathParams(radius=radius, time_limit=5.0))
        per_leg = ref_time / len(legs) if split else ref_time
        ref = OmplPathPlanner(OmplPathParams(radius=radius, time_limit=1.0, improve_time=per_leg, simplify=False))
        la = lr = lref = ta = tr = 0.0
        ok_a = ok_r = True
        for start, goal in legs:
            a = grid.plan(q, start, goal)
            r = first.plan(q, start, goal)
            f = ref.plan(q, start, goal)
            ok_a &= safe(a, truth, radius)
            ok_r &= safe(r, truth, radius)
            la, lr, lref = la + a.length, lr + r.length, lref + (f.length if f.found else np.nan)
            ta, tr = ta + a.plan_seconds, tr + r.plan_seconds
        astar["ok"] += ok_a
        rrtc["ok"] += ok_r
        astar["t"].append(ta)
        rrtc["t"].append(tr)
        astar["ratio"].append(la / lref)
        rrtc["ratio"].append(lr / lref)
    for name, d in (("grid A*", astar), ("RRTConnect+simplify", rrtc)):
        t = np.array(d["t"]) * 1e3
        ratio = np.array(d["ratio"])
        print(
            f"{label:8s} {name:20s} success {d['ok']}/{n} = {100.0 * d['ok'] / n:5.1f} %   "
            f"length / InformedRRT*({ref_time:g} s{' per layout' if split else ''}): median {np.nanmedian(ratio):.3f} max {np.nanmax(ratio):.3f}   "
            f"plan ms: median {np.median(t):.1f} p99 {np.percentile(t, 99):.1f}"
        )
        worst = np.argsort(-np.nan_to_num(ratio, nan=-1.0))[:5]
        print(f"{'':8s} {'':20s} worst: " + ", ".join(f"seed {seeds[i]} {ratio[i]:.3f}" for i in worst))


def fly_local(lp, world, waypoints, radius, max_replans=400):
    """Receding horizon at 10 Hz through ``waypoints`` (a stop at each, perfect tracking): success (every
    waypoint reached, the flown curve never closer than ``radius`` to the triangles, checked with Open3D),
    per-replan wall and CPU seconds."""
    t, p, v, a = 0.0, waypoints[0], np.zeros(3), np.zeros(3)
    flown, wall, cpu = [], [], []
    for goal in waypoints[1:]:
        plan, reached = None, False
        for _ in range(max_replans):
            r = lp.replan(t, p, v, a, goal)
            wall.append(r.plan_seconds)
            cpu.append(r.plan_cpu_seconds)
            if r.status == "ok":
                plan = r.trajectory
            if plan is None:
                break
            if r.status == "ok" and r.reaches_goal:
                flown.append(plan.sample(np.linspace(t, plan.t_end, 200)).p_W)
                t, p, v, a = plan.t_end, np.asarray(goal, float), np.zeros(3), np.zeros(3)
                reached = True
                break
            flown.append(plan.sample(np.linspace(t, t + 0.1, 11)).p_W)
            t += 0.1
            s = plan.sample(t)
            p, v, a = s.p_W[0], s.v_W[0], s.a_W[0]
        if not reached:
            return False, wall, cpu
    return float(truth_distance(world)(np.vstack(flown)).min()) >= radius - 1e-5, wall, cpu


def run_local(cases, label):
    """``cases``: (seed, (world, esdf, waypoints, radius, params)) per layout."""
    times, cpu, ok, n, failed = [], [], 0, 0, []
    for seed, (world, esdf, waypoints, radius, params) in cases:
        success, w, c = fly_local(BsplineLocalPlanner(esdf, params), world, waypoints, radius)
        times += w
        cpu += c
        n += 1
        ok += success
        if not success:
            failed.append(seed)
    t, c = np.array(times) * 1e3, np.array(cpu) * 1e3
    print(
        f"{label:8s} local B-spline (known map, perfect tracking: a planner-only figure) "
        f"success {ok}/{n} = {100.0 * ok / n:5.1f} %   "
        f"replan ms: median {np.median(t):.2f} p99 {np.percentile(t, 99):.2f} "
        f"(CPU: median {np.median(c):.2f} p99 {np.percentile(c, 99):.2f}; {t.size} replans; load "
        f"{os.getloadavg()[0]:.1f})" + (f"   failed: {failed}" if failed else "")
    )


def local_forests(seeds):
    for seed in seeds:
        world, _, start, goal, radius = forest_case(seed)
        esdf = esdf_from_world(world, RES_FOREST, [[-17.0, -8.0, 0.0], [17.0, 8.0, 3.0]])
        yield seed, (world, esdf, [start, goal], radius, LocalPlannerParams(radius=radius, v_max=2.0, a_max=3.0))


RES_TUNNEL_LOCAL = 0.025


def local_tunnels(seeds):
    """Entry, each frame's centre, exit of a tunnel course at radius 0.15 on a 2.5 cm ESDF of the known world;
    the collision cost acts from 15 cm beyond the radius (5 cm fails more short legs between offset frames)."""
    for seed in seeds:
        c = tunnel_course_layout(seed)
        lo, hi = c.path_W.min(0) - 1.0, c.path_W.max(0) + 1.0
        lo[2] = 0.0
        esdf = esdf_from_world(c.world, RES_TUNNEL_LOCAL, np.stack([lo, hi]))
        pts = [c.entry_W] + [np.asarray(f.centre_W) for f in c.frames] + [c.exit_W]
        z = np.array(pts)[:, 2]
        params = LocalPlannerParams(
            radius=0.15,
            margin=0.15,
            v_max=1.5,
            a_max=2.0,
            dt=0.1,
            horizon=4.0,
            z_min=max(0.2, float(z.min()) - 0.5),
            z_max=float(z.max()) + 0.5,
        )
        yield seed, (c.world, esdf, pts, 0.15, params)


def run_global(cases):
    """The global plan on each forest (grid A* then the clearance-keeping min-snap with optimised times):
    wall and CPU time of the search alone and of search + min-snap (target: global plan <= 20 ms median)."""
    planner = GlobalPlanner(GlobalPlannerParams(search="astar", radius=RADIUS_FOREST))
    rows, ok, n = [], 0, 0
    for _, (_world, q, legs, _radius) in cases:
        ((start, goal),) = legs
        g = planner.plan(q, start, goal)
        n += 1
        ok += g.ok
        rows.append(
            (
                g.search_seconds,
                g.search_cpu_seconds,
                g.plan_seconds,
                g.plan_cpu_seconds,
                0 if g.motion is None else g.motion.inserted,
                g.path.path_W.shape[0],
                np.nan if g.trajectory is None else g.trajectory.snap_cost(),
                np.nan if g.motion is None else g.motion.min_clearance,
            )
        )
    a = np.array(rows)
    ms = lambda x: f"median {np.median(x) * 1e3:6.1f} p99 {np.percentile(x, 99) * 1e3:6.1f}"  # noqa: E731
    print(
        f"forest   global plan (known map: a planner-only figure) ok {ok}/{n}; load {os.getloadavg()[0]:.1f}; waypoints median "
        f"{np.median(a[:, 5]):.0f}, inserted median {np.median(a[:, 4]):.0f} max {a[:, 4].max():.0f}"
    )
    print(f"{'':8s} search only ms       wall {ms(a[:, 0])}   CPU {ms(a[:, 1])}")
    print(f"{'':8s} search + min-snap ms wall {ms(a[:, 2])}   CPU {ms(a[:, 3])}")
    print(
        f"{'':8s} snap cost [m^2/s^7]  median {np.nanmedian(a[:, 6]):.4f} sum {np.nansum(a[:, 6]):.4f}; "
        f"min clearance {np.nanmin(a[:, 7]):.3f} m (radius {RADIUS_FOREST})"
    )


def run_online(seeds):
    """The ``forest_global`` scenario on each forest layout: the ``global`` planner on the map built online, the
    local replanner it guides, the vehicle on the LIO; layout K flies with scenario seed K (its own sensor draws).
    Success and flight figures from each run's metrics."""
    from cufund.scenarios import load_scenario
    from cufund.scenarios.build import run_scenario

    rows = []
    for seed in seeds:
        t0 = time.perf_counter()
        m = run_scenario(load_scenario("forest_global", {"world.seed": int(seed), "seed": int(seed)})).metrics
        rows.append(m)
        print(
            f"online   seed {seed:3d} {m['status']:9s} success {m.get('success')!s:5s} goal at "
            f"{m.get('goal_reached_s') or float('nan'):5.1f} s, flown {m.get('path_length_m', float('nan')):5.1f} m, "
            f"min trunk clearance {m.get('min_clearance_m') or float('nan'):.3f} m; global: first plan "
            f"{m.get('global_status')} {m.get('global_plan_ms') or float('nan'):.1f} ms, replans "
            f"{m.get('global_replan_status')}; odometry RMSE {m.get('odometry_rmse_m', float('nan')):.3f} m "
            f"({time.perf_counter() - t0:.0f} s wall)"
        )
    ok = sum(bool(m.get("success")) and m["status"] != "crashed" for m in rows)
    first = np.array([m.get("global_plan_ms") or np.nan for m in rows], dtype=float)
    print(
        f"online   forest_global (map built online, flown on the LIO) success {ok}/{len(rows)}; first global plan "
        f"ms median {np.nanmedian(first):.1f}; load {os.getloadavg()[0]:.1f}"
    )


def run_scalar():
    """Per-call cost of the scalar clearance query from Python, next to a C builtin of similar arity
    (math.hypot: the floor of any call from Python) and the numpy path."""
    _, q, _, _, _ = forest_case(0)
    f, s = q.clearance_xyz, q.segment_free_xyz
    p = np.array([1.0, 2.0, 0.5])
    n = 200_000

    def per_call(stmt, **names):
        # CPU time of this thread (preemption by other processes excluded), best of 7
        return min(timeit.repeat(stmt, globals=names, number=n, repeat=7, timer=time.thread_time)) / n * 1e9

    base = per_call("hypot(1.0, 2.0, 0.5)", hypot=math.hypot)
    for name, ns in (
        ("clearance_xyz(x, y, z)", per_call("f(1.0, 2.0, 0.5)", f=f)),
        ("pybind11 method (old)", per_call("g(1.0, 2.0, 0.5)", g=q._core.clearance)),
        ("clearance(p) numpy (3,)", per_call("c(p)", c=q.clearance, p=p)),
        ("segment_free_xyz 10 cm", per_call("s(1.0, 2.0, 0.5, 1.1, 2.0, 0.5, 0.1)", s=s)),
    ):
        print(f"scalar   {name:24s} {ns:7.0f} ns per call ({ns / base:4.1f}x math.hypot's {base:.0f} ns)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--forests", type=int, default=200)
    ap.add_argument("--tunnels", type=int, default=200)
    ap.add_argument("--ref-time", type=float, default=5.0)
    ap.add_argument("--local", type=int, default=200)
    ap.add_argument("--local-tunnels", type=int, default=200, help="the local replanner through N tunnel courses")
    ap.add_argument(
        "--global", dest="global_", type=int, default=0, help="only the global plan (A* + min-snap) timing on N forests"
    )
    ap.add_argument("--scalar", action="store_true", help="only the scalar clearance call's cost")
    ap.add_argument(
        "--online", type=int, default=0, help="only the forest_global scenario (online map, LIO) on N layouts"
    )
    ap.add_argument("--first-seed", type=int, default=0, help="layouts first-seed .. first-seed + N - 1")
    ap.add_argument("--seeds", type=int, nargs="*", help="only these layouts (overrides --first-seed and the counts)")
    ap.add_argument(
        "--split-ref",
        action="store_true",
        help="tunnels: --ref-time per layout, shared by its 6 legs (else per leg: 6x longer)",
    )
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    if args.scalar:
        run_scalar()
        return

    def forests():
        for seed in args.seeds if args.seeds else range(args.first_seed, args.first_seed + args.forests):
            world, q, s, g, r = forest_case(seed)
            yield seed, (world, q, [(s, g)], r)

    def tunnels():
        for seed in args.seeds if args.seeds else range(args.first_seed, args.first_seed + args.tunnels):
            c = tunnel_course_layout(seed)
            r = 0.15
            lo, hi = c.path_W.min(0) - 1.0, c.path_W.max(0) + 1.0
            lo[2] = 0.0
            q = clearance_from_world(c.world, 0.025, np.stack([lo, hi]))
            pts = [c.entry_W] + [np.asarray(f.centre_W) for f in c.frames] + [c.exit_W]
            yield seed, (c.world, q, list(zip(pts[:-1], pts[1:], strict=True)), r)

    t0 = time.perf_counter()
    if args.online:
        run_online(args.seeds or range(args.first_seed, args.first_seed + args.online))
        print(f"total {time.perf_counter() - t0:.0f} s")
        return
    if args.global_:
        seeds = args.seeds or range(args.first_seed, args.first_seed + args.global_)
        args.forests, args.seeds = len(seeds), list(seeds)
        run_global(forests())
        print(f"total {time.perf_counter() - t0:.0f} s")
        return
    if args.forests:
        run(forests(), args.ref_time, "forest")
    if args.tunnels:
        run(tunnels(), args.ref_time, "tunnel", split=args.split_ref)
    if args.local:
        run_local(local_forests(args.seeds or range(args.first_seed, args.first_seed + args.local)), "forest")
    if args.local_tunnels:
        run_local(local_tunnels(args.seeds or range(args.first_seed, args.first_seed + args.local_tunnels)), "tunnel")
    print(f"total {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
