"""Sweeps at scale: many variants of a scenario as Dask tasks, on a local cluster (127.0.0.1) or any Dask cluster.

```python
import cufund.apps.sweep

frame = cufund.apps.sweep.run({"scenario": "square", "grid": {"controller.kind": ["pid", "geometric"]}}, out="sw")
```

See :mod:`cufund.apps.sweep.spec` for the sweep file. With ``out``, the sweep writes each variant's run folder under
``out/variants/<key>/``, ``results.parquet``, ``summary.md`` and ``plots/``; run again, it skips the variants
already finished (keyed by the hash of their resolved configuration).
"""

from __future__ import annotations

import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .execute import Outcome, execute, local_client, run_variant
from .results import WALL_METRICS, is_wall_metric, load_records, results_frame, write_record
from .spec import SweepSpec, Variant, config_key, load_spec

__all__ = [
    "WALL_METRICS",
    "SweepSpec",
    "Variant",
    "config_key",
    "is_wall_metric",
    "load_spec",
    "local_client",
    "run",
    "run_variant",
]


def run(
    spec: str | Path | Mapping[str, Any] | SweepSpec,
    client: Any = None,
    *,
    out: str | Path | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    heavy: bool = False,
    plots: bool = True,
    progress: bool | None = None,
) -> Any:
    """Runs a sweep and returns its results as a ``pandas.DataFrame`` (one row per variant, see
    :func:`cufund.apps.sweep.results.results_frame`).

    ``spec``: a sweep file, a mapping with its keys, or a :class:`SweepSpec`. Every variant is resolved and
    validated first: a bad override raises :class:`cufund.ConfigError` naming it, before any variant runs.
    ``client``: a ``distributed.Client`` to run on; else one on ``scheduler`` (``tcp://HOST:8786``); else a
    ``LocalCluster`` on 127.0.0.1 with ``workers`` single-threaded processes (default one per CPU).
    ``out``: the sweep folder (resumable); without it nothing is written. ``heavy`` keeps each variant's
    ``run.mcap`` and ``replay.html``; ``plots`` its ``trajectory.png`` and the sweep's plots.
    ``progress``: a progress bar with ETA on stderr (default: when stderr is a terminal).

    The frame's ``attrs["ran"]`` and ``attrs["reused"]`` list the keys run now and those found finished in ``out``.
    Ctrl-C (``KeyboardInterrupt``) cancels the pending variants, writes the outputs of what finished, and
    propagates.
    """
    sweep = load_spec(spec)
    variants = sweep.variants(validate=True)
    out_path = None if out is None else Path(out)
    if out_path is not None:
        from cufund.scenarios.build import out_dir_problem

        problem = out_dir_problem(out_path)
        if problem:
            from cufund.core.config import ConfigError

            raise ConfigError(problem.replace("--out", "out", 1))
    records = load_records(out_path)
    reused = sorted({v.key for v in variants if v.key in records})
    todo: dict[str, Variant] = {}
    for v in variants:  # identical configurations (e.g. equal draws) run once
        if v.key not in records and v.key not in todo:
            todo[v.key] = v
    if progress is None:
        progress = sys.stderr.isatty()

    def on_done(variant: Variant, outcome: Outcome) -> None:
        if out_path is not None:
            records[variant.key] = write_record(out_path, variant, outcome)
        else:
            records[variant.key] = {
                "key": variant.key,
                "status": outcome.status,
                "message": outcome.message,
                "metrics": outcome.metrics,
                "variant_wall_s": outcome.variant_wall_s,
                "attempts": outcome.attempts,
            }

    try:
        if todo:
            with _client(client, scheduler, workers) as c:
                execute(
                    c,
                    list(todo.values()),
                    on_done,
                    files=out_path is not None,
                    heavy=heavy,
                    plots=plots,
                    progress=progress,
                )
    finally:
        frame = results_frame(variants, records, sweep.swept_keys, sweep.repeats, out_path)
        frame.attrs["ran"] = sorted(k for k in todo if k in records)
        frame.attrs["reused"] = reused
        if out_path is not None:
            from .report import write_outputs

            write_outputs(out_path, sweep, frame, len(variants), plots=plots)
    return frame


class _client:
    """The given client, one on ``scheduler``, or a local cluster's (closed on exit)."""

    def __init__(self, client: Any, scheduler: str | None, workers: int | None) -> None:
        self.client, self.scheduler, self.workers = client, scheduler, workers
        self._cm: Any = None

    def __enter__(self) -> Any:
        if self.client is not None:
            return self.client
        if self.scheduler is not None:
            from distributed import Client

            self._cm = Client(self.scheduler)
        else:
            self._cm = local_client(self.workers)
        return self._cm.__enter__()

    def __exit__(self, *exc: Any) -> None:
        if self._cm is not None:
            self._cm.__exit__(*exc)
