"""Running a sweep's variants as Dask tasks: a local cluster bound to 127.0.0.1 by default, or any cluster by its
scheduler's address; a variant whose worker dies is retried once, then recorded failed with the reason."""

from __future__ import annotations

import contextlib
import logging
import os
import socket
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["Outcome", "execute", "local_client", "run_variant"]

THREADS_ENV = "CUFUND_NUM_THREADS"


@dataclass
class Outcome:
    """What one variant left: its metrics and run-folder files, or why it failed."""

    status: str
    """The run's status (completed, timeout, crashed, diverged, aborted) or ``failed`` (the task never finished:
    its worker died twice, or the run raised)."""
    message: str = ""
    metrics: dict[str, Any] = field(default_factory=dict)
    files: dict[str, bytes] = field(default_factory=dict)
    variant_wall_s: float = float("nan")
    """Wall time of the task on its worker (build, run, files) [s]."""
    attempts: int = 1
    worker: str = ""


def run_variant(config: Any, files: bool = True, heavy: bool = False, plots: bool = True) -> Outcome:
    """The Dask task: runs ``config`` and returns its outcome, the run folder's files as bytes (so a remote worker
    needs no shared file system). ``heavy`` adds ``run.mcap`` and ``replay.html``."""
    os.environ.setdefault(THREADS_ENV, "1")  # effective if the C++ pool has not started in this worker yet
    from cufund.scenarios.build import run_scenario
    from cufund.scenarios.run_folder import run_into_folder

    t0 = time.perf_counter()
    data: dict[str, bytes] = {}
    if files:
        with tempfile.TemporaryDirectory(prefix="cufund-sweep-") as tmp:
            run = run_into_folder(config, tmp, log=heavy, plots=plots, replay=heavy)
            data = {p.name: p.read_bytes() for p in sorted(Path(tmp).iterdir()) if p.is_file()}
    else:
        run = run_scenario(config)
    return Outcome(
        run.result.status.value,
        run.result.message,
        dict(run.metrics),
        data,
        time.perf_counter() - t0,
        worker=f"{socket.gethostname()}:{os.getpid()}",
    )


@contextlib.contextmanager
def local_client(workers: int | None = None) -> Iterator[Any]:
    """A ``distributed.Client`` on a fresh ``LocalCluster``: ``workers`` single-threaded worker processes (default:
    one per CPU this process may use), every socket on 127.0.0.1 (the scheduler's HTTP endpoints, and its dashboard
    when bokeh is installed, on a free port), ``CUFUND_NUM_THREADS=1`` in each worker, and a task whose worker dies
    marked failed at once (the sweep retries it once itself); workers ignore SIGINT (the client stops them)."""
    import dask
    from distributed import Client, LocalCluster

    n = workers if workers is not None else len(os.sched_getaffinity(0))
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ValueError(f"workers must be a positive integer, got {workers!r}")
    # no statistical profiler in the workers (it samples every thread's stack every 10 ms; nobody reads it here)
    with dask.config.set({"distributed.scheduler.allowed-failures": 0, "distributed.worker.profile.enabled": False}):
        cluster = LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address="127.0.0.1:0",
            worker_dashboard_address=None,
            silence_logs=logging.CRITICAL,
            env={THREADS_ENV: "1"},
        )
    try:
        with Client(cluster) as client:
            from .worker_plugin import IgnoreInterrupts

            client.register_plugin(IgnoreInterrupts(), name="cufund-sweep-ignore-sigint")
            yield client
    finally:
        cluster.close()


def execute(
    client: Any,
    todo: list[Any],
    on_done: Callable[[Any, Outcome], None],
    *,
    files: bool,
    heavy: bool,
    plots: bool,
    progress: bool,
) -> None:
    """Submits one task per item of ``todo`` (each with ``.config`` and ``.key``) and calls ``on_done(item, outcome)``
    in this thread as each ends. A task whose worker died (``KilledWorker``) is submitted once more (unless the
    scheduler retries such tasks itself: its ``distributed.scheduler.allowed-failures`` > 0); a second death, or an
    exception in the run, is recorded as ``failed`` with the reason. On ``KeyboardInterrupt`` the pending tasks
    are cancelled and the interrupt propagates (what finished was already handed to ``on_done``)."""
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    scheduler_retries = _scheduler_retries(client)  # 0 on local_client's; a remote one may retry itself
    bar = _progress(len(todo), progress)
    meta: dict[Any, tuple[Any, int]] = {}

    def submit(item: Any, attempt: int) -> Any:
        fut = client.submit(
            run_variant,
            item.config,
            files,
            heavy,
            plots,
            key=f"cufund-sweep-{item.key}-{attempt}",
            pure=False,
            retries=0,
        )
        meta[fut] = (item, attempt)
        return fut

    pending = as_completed([submit(item, 1) for item in todo])
    try:
        for fut in pending:
            item, attempt = meta.pop(fut)
            if fut.status == "finished":
                outcome = fut.result()
                outcome.attempts = attempt
            else:
                exc = fut.exception()
                if isinstance(exc, KilledWorker) and attempt == 1 and scheduler_retries == 0:
                    pending.add(submit(item, 2))
                    fut.release()
                    continue
                if isinstance(exc, KilledWorker):
                    deaths = "twice" if scheduler_retries == 0 else f"{scheduler_retries + 1} times"
                    reason = f"its worker died {deaths} while running it ({type(exc).__name__}: {exc})"
                else:
                    reason = f"{type(exc).__name__}: {exc}"
                outcome = Outcome("failed", reason, attempts=attempt)
            fut.release()
            on_done(item, outcome)
            bar.update(1)
    except BaseException:
        client.cancel(list(meta))
        raise
    finally:
        bar.close()


def _scheduler_retries(client: Any) -> int:
    """How many times the scheduler itself re-runs a task whose worker died (its ``allowed-failures``)."""
    try:
        # a lambda travels by value: a remote scheduler need not have cufund installed
        return int(client.run_on_scheduler(lambda dask_scheduler: dask_scheduler.allowed_failures))
    except Exception:  # a scheduler that refuses run_on_scheduler: count on our own retry
        return 0


def _progress(total: int, enabled: bool) -> Any:
    from tqdm import tqdm

    return tqdm(total=total, unit="variant", desc="sweep", disable=not enabled, smoothing=0.1, dynamic_ncols=True)
