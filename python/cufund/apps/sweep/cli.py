"""``cufund sweep SWEEP.yaml --out DIR [--scheduler tcp://HOST:8786] [--workers N]``.

Exit codes: 0 every variant ran (whatever each flight's status), 1 some variant failed (its worker died twice or
the run raised) or the sweep was interrupted, 2 an invalid sweep (a one-line message naming the field), checked
before any variant runs.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from ..arguments import add_overrides

__all__ = ["add_arguments", "run_cli"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("sweep", type=Path, help="the sweep file (YAML: scenario, set, grid, random, repeats)")
    p.add_argument(
        "--out",
        type=Path,
        required=True,
        help="the sweep folder: results.parquet, summary.md, plots/, variants/<key>/; an existing one is "
        "resumed (finished variants are skipped)",
    )
    p.add_argument(
        "--scheduler",
        metavar="tcp://HOST:8786",
        help="run on this Dask scheduler (default: a local cluster on 127.0.0.1)",
    )
    p.add_argument(
        "--workers", type=int, metavar="N", help="worker processes of the local cluster (default: one per CPU)"
    )
    add_overrides(p, help="override a field in every variant (added to the file's set; repeatable)")
    p.add_argument("--heavy", action="store_true", help="keep each variant's run.mcap and replay.html")
    p.add_argument("--no-plots", action="store_true", help="skip trajectory.png and the sweep's plots")


def run_cli(args: argparse.Namespace) -> int:
    from cufund.core.config import ConfigError
    from cufund.scenarios.schema import parse_overrides

    from . import run
    from .spec import load_spec

    try:
        if args.workers is not None and args.workers < 1:
            raise ConfigError(f"--workers must be a positive integer, got {args.workers}")
        if args.workers is not None and args.scheduler is not None:
            raise ConfigError("--workers sizes the local cluster; it cannot be given with --scheduler")
        spec = load_spec(args.sweep)
        if args.overrides:
            spec = replace(spec, set={**spec.set, **parse_overrides(args.overrides)})
        frame = run(
            spec,
            out=args.out,
            workers=args.workers,
            scheduler=args.scheduler,
            heavy=args.heavy,
            plots=not args.no_plots,
        )  # every variant validated before any runs
    except (ConfigError, OSError) as e:
        print(f"cufund: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(
            f"cufund: sweep interrupted; what finished is in {args.out} (run the same command to resume)",
            file=sys.stderr,
        )
        return 1
    counts = frame["status"].value_counts().to_dict() if len(frame) else {}
    print(", ".join(f"{n} {s}" for s, n in counts.items()) or "no variants")
    print(f"ran {len(frame.attrs['ran'])}, reused {len(frame.attrs['reused'])}")
    print(f"sweep folder: {args.out.resolve()}")
    return 1 if counts.get("failed") else 0
