"""The search over many seeds (issue 26's benchmark, not a test): precision and recall of the confirmed finds per
seed and in total, position errors, wall time and real-time factor.

    .venv/bin/python benchmarks/bench_search.py                  # seeds 0..19, two processes
    .venv/bin/python benchmarks/bench_search.py --seeds 5 --first 100 --jobs 1
    .venv/bin/python benchmarks/bench_search.py --set perception.conf=0.35 --json /tmp/search.json
    .venv/bin/python benchmarks/bench_search.py --out /tmp/search_runs   # + each run's folder (run.mcap)

Seed K flies ``cufund run search --seed K`` (layout K of the trees and people, and its own sensor noise,
calibration and plant draws under the scenario's ``realistic`` profile). Each run is the full stack (rendered
stereo pair, the shipped people model, stereo placement, the ESKF estimate, the search mission, 1 kHz physics) in
its own process, at ``nice`` 10; with ``--jobs`` > 1 the real-time factors are those of processes sharing the
cores (about 140-200 s of wall per run on 2 shared cores).

The totals pool the finds: precision = right finds / finds over all seeds, recall = people found / people placed;
the per-seed means are printed beside them.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import sys
import time
from typing import Any

import numpy as np


def _nice() -> None:
    """Each worker process lowers its priority once (os.nice adds: a worker flies several seeds)."""
    os.nice(10)


def _one(job: tuple[int, list[str], str | None]) -> dict[str, Any]:
    seed, overrides, out = job
    from cufund.scenarios import load_scenario, parse_overrides
    from cufund.scenarios.build import run_scenario
    from cufund.scenarios.run_folder import run_into_folder

    t0 = time.perf_counter()
    try:
        config = load_scenario("search", parse_overrides([f"seed={seed}", *overrides]))
        if out is None:
            run = run_scenario(config)
        else:  # the run folder (run.mcap: its detections and estimates can be replayed through the mission)
            run = run_into_folder(config, os.path.join(out, f"seed_{seed}"), plots=False, replay=False)
        m = dict(run.metrics)
    except Exception as e:  # one failed run is a row of the table, not the end of the benchmark
        m = {"status": f"exception: {type(e).__name__}: {e}"}
    m["seed"], m["wall_s"] = seed, time.perf_counter() - t0
    return m


def _counts(m: dict[str, Any]) -> tuple[int, int, int]:
    """(finds, right finds, people) of one run's metrics (none of a run that raised)."""
    right = len(m.get("search_position_error_m") or [])
    return int(m.get("search_finds") or 0), right, int(m.get("search_people") or 0)


def _row(m: dict[str, Any]) -> str:
    finds, right, people = _counts(m)
    err = m.get("search_position_error_m") or []
    t = m.get("search_time_s")
    return (
        f"| {m['seed']} | {m.get('status')} | {m.get('search_precision', float('nan')):.2f} | "
        f"{m.get('search_recall', float('nan')):.2f} | {right}/{finds} | {right}/{people} | "
        f"{max(err) if err else float('nan'):.2f} | {'-' if t is None else f'{t:.1f}'} | "
        f"{m['wall_s']:.0f} | {m.get('real_time_factor') or float('nan'):.2f} |"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seeds", type=int, default=20, help="how many seeds (default 20)")
    ap.add_argument("--first", type=int, default=0, help="first seed (default 0)")
    ap.add_argument("--jobs", type=int, default=2, help="processes in parallel (default 2, at most 2)")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    ap.add_argument("--json", help="write every run's search metrics here")
    ap.add_argument(
        "--out",
        help="write each run's folder here (seed_K/: run.mcap, metrics.json, found_people.json), e.g. to replay "
        "the logged detections through the mission with other settings",
    )
    args = ap.parse_args()
    if not 1 <= args.jobs <= 2:
        ap.error(f"--jobs must be 1 or 2 (the machine's 2 cores are shared), got {args.jobs}")
    if args.seeds < 1:
        ap.error(f"--seeds must be >= 1, got {args.seeds}")
    from cufund.core.config import ConfigError
    from cufund.scenarios import load_scenario, parse_overrides

    try:  # refused here, not once per seed in the workers
        if "seed" in parse_overrides(args.overrides):
            ap.error("--set seed=... would fly every run on one seed: use --first and --seeds")
        for seed in (args.first, args.first + args.seeds - 1):
            load_scenario("search", parse_overrides([f"seed={seed}", *args.overrides]))
    except ConfigError as e:
        ap.error(str(e))
    jobs = [(s, args.overrides, args.out) for s in range(args.first, args.first + args.seeds)]
    print(
        f"search benchmark: seeds {args.first}..{args.first + args.seeds - 1}, {args.jobs} job(s), "
        f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.1f} {' '.join(args.overrides)}",
        flush=True,
    )
    t0 = time.perf_counter()
    results = []
    with mp.get_context("spawn").Pool(args.jobs, initializer=_nice) as pool:
        for m in pool.imap_unordered(_one, jobs):
            results.append(m)
            print(f"  seed {m['seed']} done: {_row(m)}", flush=True)
    wall = time.perf_counter() - t0
    results.sort(key=lambda m: m["seed"])
    if args.json:
        keep = ("seed", "status", "wall_s", "sim_time_s", "real_time_factor")
        rows = [{k: v for k, v in m.items() if k in keep or k.startswith("search_")} for m in results]
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump(rows, f, indent=1)
    print(
        "\n| seed | status | precision | recall | right/finds | found/people | worst error [m] | search_time_s |"
        " wall [s] | RTF |\n|---|---|---|---|---|---|---|---|---|---|"
    )
    for m in results:
        print(_row(m))
    counts = np.array([_counts(m) for m in results]).reshape(-1, 3)
    finds, right, people = counts.sum(axis=0)
    errors = np.array([e for m in results for e in m.get("search_position_error_m") or []], dtype=float)
    completed = sum(m.get("status") == "completed" for m in results)
    print(f"\nruns completed: {completed}/{len(results)}")
    print(
        f"total: precision {right / max(finds, 1):.3f} ({right} of {finds} finds right), recall "
        f"{right / max(people, 1):.3f} ({right} of {people} people) (targets >= 0.9 both)"
    )
    prec = [m["search_precision"] for m in results if "search_precision" in m]
    rec = [m["search_recall"] for m in results if "search_recall" in m]
    if prec:
        print(
            f"per seed: mean precision {np.mean(prec):.3f} (min {min(prec):.2f}), mean recall {np.mean(rec):.3f} "
            f"(min {min(rec):.2f}); seeds with both >= 0.9: {sum(p >= 0.9 and r >= 0.9 for p, r in zip(prec, rec, strict=True))}"
        )
    if errors.size:
        print(f"position error of right finds: median {np.median(errors):.2f} m, max {errors.max():.2f} m")
    rtf = np.array([m["real_time_factor"] for m in results if m.get("real_time_factor")], dtype=float)
    if rtf.size:
        print(
            f"real-time factor (wall, {args.jobs} process(es) sharing the cores): median {np.median(rtf):.2f}x, "
            f"min {rtf.min():.2f}x, max {rtf.max():.2f}x"
        )
    print(f"wall time: {wall:.0f} s for {len(results)} runs; load {os.getloadavg()[0]:.1f} at the end")
    return 0


if __name__ == "__main__":
    sys.exit(main())
