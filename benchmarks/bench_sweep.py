"""Sweep throughput: the square's variants per minute on Dask (`cufund.sweep.run` on a 2-worker LocalCluster)
against a plain `multiprocessing.Pool(2)` running the same task on the same variants, and Dask with 1 vs 2 workers.

Both sides are warmed up first (workers started, cufund imported in each), so the figures are the steady-state
cost of a sweep; the cluster's start-up is printed apart. No files are written (``out=None``) on either side.
The machine is shared: rounds alternate the sides, and every round is printed.

    .venv/bin/python benchmarks/bench_sweep.py [--variants 12] [--duration 10] [--rounds 2]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import time
from functools import partial


def _warm(_: int) -> int:
    import cufund.scenario_build  # noqa: F401

    return os.getpid()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", type=int, default=12)
    ap.add_argument("--duration", type=float, default=10.0, help="simulated seconds per variant")
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()
    os.environ["CUFUND_NUM_THREADS"] = "1"  # the Pool's workers too (spawned after this)

    import cufund.sweep as sweep
    from cufund.sweep.execute import run_variant

    gains = [2.0 + 2.0 * i / max(args.variants - 1, 1) for i in range(args.variants)]
    spec = sweep.load_spec({"scenario": "square", "set": {"duration": args.duration},
                            "grid": {"controller.position.xy_p": gains}})
    configs = [v.config for v in spec.variants()]
    per_min = lambda seconds: 60.0 * len(configs) / seconds  # noqa: E731
    print(f"{len(configs)} variants of the square, {args.duration:g} s simulated each, CUFUND_NUM_THREADS=1; "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}")

    results: dict[str, list[float]] = {"pool2": [], "dask2": [], "dask1": []}
    t0 = time.perf_counter()
    with sweep.local_client(2) as c2:
        start2 = time.perf_counter() - t0
        c2.run(_warm, 0)
        t0 = time.perf_counter()
        with sweep.local_client(1) as c1:
            start1 = time.perf_counter() - t0
            c1.run(_warm, 0)
            with mp.get_context("spawn").Pool(2) as pool:
                pool.map(_warm, range(2))
                for r in range(args.rounds):
                    t = time.perf_counter()
                    pool_out = pool.map(partial(run_variant, files=False), configs, chunksize=1)
                    results["pool2"].append(time.perf_counter() - t)
                    t = time.perf_counter()
                    frame = sweep.run(spec, c2, progress=False)
                    results["dask2"].append(time.perf_counter() - t)
                    t = time.perf_counter()
                    sweep.run(spec, c1, progress=False)
                    results["dask1"].append(time.perf_counter() - t)
                    print(f"round {r + 1}: Pool(2) {per_min(results['pool2'][-1]):.1f}/min, Dask 2 workers "
                          f"{per_min(results['dask2'][-1]):.1f}/min, Dask 1 worker {per_min(results['dask1'][-1]):.1f}"
                          f"/min (load average {os.getloadavg()[0]:.1f})", flush=True)
    same = frame["tracking_rmse_m"].tolist() == [o.metrics["tracking_rmse_m"] for o in pool_out]
    best = {k: min(v) for k, v in results.items()}
    print(f"cluster start-up: 2 workers {start2:.1f} s, 1 worker {start1:.1f} s (not in the rates)")
    print(f"best of {args.rounds}: Pool(2) {per_min(best['pool2']):.1f} variants/min, Dask 2 workers "
          f"{per_min(best['dask2']):.1f}/min, Dask 1 worker {per_min(best['dask1']):.1f}/min")
    print(f"Dask overhead vs Pool(2): {100 * (best['dask2'] / best['pool2'] - 1):+.1f} % (target <= 10 %); "
          f"speed-up 1 -> 2 workers: {best['dask1'] / best['dask2']:.2f}x; same metrics as the Pool: {same}")


if __name__ == "__main__":
    main()
