"""Sweep throughput: the square's variants per minute on Dask (`cufund.apps.sweep.run` on a 2-worker LocalCluster)
against a plain `multiprocessing.Pool(2)` running the same task on the same variants, and Dask with 1 vs 2 workers.

Both sides are warmed up first (workers started, cufund imported in each), so the figures are the steady-state
cost of a sweep; the cluster's start-up is printed apart. No files are written (``out=None``) on either side.
The machine is shared: each round runs the three sides in a rotated order, every round is printed, and the CPU
seconds spent per variant (this process, which hosts the scheduler, plus the worker processes) are printed too:
they move much less with the host's load than wall time does.

    .venv/bin/python benchmarks/bench_sweep.py [--variants 12] [--duration 10] [--rounds 2]
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import os
import statistics
import time
from functools import partial


def _warm(_: int) -> int:
    import cufund.scenarios.build  # noqa: F401

    return os.getpid()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", type=int, default=12)
    ap.add_argument("--duration", type=float, default=10.0, help="simulated seconds per variant")
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()
    import dask.config
    import distributed  # noqa: F401  (its config defaults)

    # the Pool's workers (spawned after this) get what a Dask nanny gives its workers: CUFUND_NUM_THREADS=1 and
    # dask's pre-spawn environment (OMP/MKL/OpenBLAS threads 1, malloc trim threshold)
    os.environ.update({k: str(v) for k, v in dask.config.get("distributed.nanny.pre-spawn-environ").items()})
    os.environ["CUFUND_NUM_THREADS"] = "1"

    import cufund.apps.sweep as sweep
    from cufund.apps.sweep.execute import run_variant

    gains = [2.0 + 2.0 * i / max(args.variants - 1, 1) for i in range(args.variants)]
    spec = sweep.load_spec(
        {"scenario": "square", "set": {"duration": args.duration}, "grid": {"controller.position.xy_p": gains}}
    )
    configs = [v.config for v in spec.variants()]
    per_min = lambda seconds: 60.0 * len(configs) / seconds  # noqa: E731
    print(
        f"{len(configs)} variants of the square, {args.duration:g} s simulated each, CUFUND_NUM_THREADS=1; "
        f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}"
    )

    labels = {"pool2": "Pool(2)", "dask2": "Dask 2 workers", "dask1": "Dask 1 worker"}
    wall: dict[str, list[float]] = {k: [] for k in labels}
    cpu_s: dict[str, list[float]] = {k: [] for k in labels}
    outputs: dict[str, object] = {}
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
                pids = {"pool2": [p.pid for p in pool._pool], "dask2": _pids(c2), "dask1": _pids(c1)}
                sides = {
                    "pool2": lambda: pool.map(partial(run_variant, files=False), configs, chunksize=1),
                    "dask2": lambda: sweep.run(spec, c2, progress=False),
                    "dask1": lambda: sweep.run(spec, c1, progress=False),
                }
                order = list(sides)
                for r in range(args.rounds):
                    for name in order[r % 3 :] + order[: r % 3]:  # rotated: no side always runs after another
                        cpu = _cpu(pids[name])
                        t = time.perf_counter()
                        outputs[name] = sides[name]()
                        wall[name].append(time.perf_counter() - t)
                        cpu_s[name].append(_cpu(pids[name]) - cpu)
                    print(
                        f"round {r + 1}: "
                        + ", ".join(f"{labels[k]} {per_min(wall[k][-1]):.1f}/min" for k in order)
                        + f" (load average {os.getloadavg()[0]:.1f})",
                        flush=True,
                    )
    frame, pool_out = outputs["dask2"], outputs["pool2"]
    for name in ("dask1", "dask2"):
        failed = outputs[name][outputs[name]["status"] == "failed"]
        assert failed.empty, f"{labels[name]}: {failed['message'].tolist()}"
    same = frame["tracking_rmse_m"].tolist() == [o.metrics["tracking_rmse_m"] for o in pool_out]
    med = {k: statistics.median(v) for k, v in wall.items()}
    cpu_med = {k: statistics.median(v) / len(configs) for k, v in cpu_s.items()}
    print(f"cluster start-up: 2 workers {start2:.1f} s, 1 worker {start1:.1f} s (not in the rates)")
    print(
        f"median of {args.rounds} rounds: " + ", ".join(f"{labels[k]} {per_min(med[k]):.1f} variants/min" for k in wall)
    )
    print(
        "CPU seconds per variant (this process + the workers' processes, median): "
        + ", ".join(f"{labels[k]} {cpu_med[k]:.3f}" for k in wall)
    )
    print(
        f"Dask overhead vs Pool(2): wall {100 * (med['dask2'] / med['pool2'] - 1):+.1f} %, CPU "
        f"{100 * (cpu_med['dask2'] / cpu_med['pool2'] - 1):+.1f} % (target <= 10 %; negative: Dask cheaper); "
        f"speed-up 1 -> 2 workers: {med['dask1'] / med['dask2']:.2f}x; same metrics as the Pool: {same}"
    )


def _pids(client) -> list[int]:
    return [*client.run(os.getpid).values(), *client.run(os.getpid, nanny=True).values()]


def _cpu(pids: list[int]) -> float:
    import psutil

    total = 0.0
    for pid in {os.getpid(), *pids}:  # a LocalCluster's nannies live in this process
        t = psutil.Process(pid).cpu_times()
        total += t.user + t.system
    return total


if __name__ == "__main__":
    main()
