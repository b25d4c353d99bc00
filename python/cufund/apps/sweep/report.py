"""A sweep's outputs: ``results.parquet``, ``summary.md`` and ``plots/`` (success rate and metric distributions
against each swept parameter, with 95 % confidence intervals)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from .results import FAILED, is_wall_metric

__all__ = ["groups", "plotted_metrics", "t_interval", "wilson_interval", "write_outputs"]

_MAX_CATEGORIES = 8
_STATUS_COLUMNS = ("key", "status", "message", "variant_wall_s", "attempts", "run_folder", "repeat")


def wilson_interval(successes: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """The Wilson score interval of a success rate (95 % by default); (nan, nan) when ``n`` is 0."""
    if n == 0:
        return (math.nan, math.nan)
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    return (max(0.0, centre - half), min(1.0, centre + half))


def t_interval(values: np.ndarray, level: float = 0.95) -> tuple[float, float, float]:
    """Mean and Student-t confidence interval of the finite ``values`` (nan bounds with fewer than 2)."""
    from scipy import stats

    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return (math.nan, math.nan, math.nan)
    mean = float(np.mean(v))
    if v.size < 2:
        return (mean, math.nan, math.nan)
    half = float(stats.t.ppf(0.5 + level / 2, v.size - 1) * np.std(v, ddof=1) / math.sqrt(v.size))
    return (mean, mean - half, mean + half)


def plotted_metrics(frame: Any, swept: list[str]) -> list[str]:
    """The flight metrics worth a distribution: numeric, not a wall time or a count, varying across the sweep."""
    out = []
    for name in frame.columns:
        if name in swept or name in _STATUS_COLUMNS or is_wall_metric(name) or name.endswith(("_samples", ".0", ".1")):
            continue
        if name in ("sim_time_s",) or name.startswith("dropped_messages"):
            continue
        col = frame[name]
        if col.dtype.kind in "fi" and col.notna().any() and col.nunique(dropna=True) > 1:
            out.append(name)
    return out


def groups(frame: Any, key: str) -> list[tuple[str, float | None, Any]]:
    """The frame split by the swept ``key``: ``(label, x or None, rows)`` per value, or per quantile bin when a
    numeric key takes more than 8 values (random draws)."""
    col = frame[key]
    values = col.dropna().unique()
    numeric = col.dtype.kind in "fi"
    if numeric and len(values) > _MAX_CATEGORIES:
        edges = np.unique(np.quantile(col.dropna().to_numpy(float), np.linspace(0, 1, _MAX_CATEGORIES + 1)))
        idx = np.clip(np.searchsorted(edges, col.to_numpy(float), side="right") - 1, 0, len(edges) - 2)
        out: list[tuple[str, float | None, Any]] = []
        for i in range(len(edges) - 1):
            rows = frame[idx == i]
            if len(rows):
                out.append((f"[{edges[i]:.4g}, {edges[i + 1]:.4g}]", float(rows[key].mean()), rows))
        return out
    try:
        ordered = sorted(values)
    except TypeError:
        ordered = sorted(values, key=str)
    return [(str(v), float(v) if numeric else None, frame[col == v]) for v in ordered]


def write_outputs(out: Path, spec: Any, frame: Any, n_variants: int, plots: bool = True) -> None:
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / "results.parquet.tmp"
    frame.to_parquet(tmp, index=False)
    tmp.replace(out / "results.parquet")
    swept = [k for k in spec.swept_keys if k in frame.columns]
    images = _plot(out / "plots", frame, swept) if plots and len(frame) else []
    (out / "summary.md").write_text(_summary(spec, frame, n_variants, swept, images, out), encoding="utf-8")


def _success(rows: Any) -> tuple[int, int]:
    return int((rows["status"] == "completed").sum()), len(rows)


def _summary(spec: Any, frame: Any, n_variants: int, swept: list[str], images: list[Path], out: Path) -> str:
    lines = [f"# Sweep of `{spec.scenario}`", ""]
    done = len(frame)
    lines.append(
        f"{done} of {n_variants} variants have a result"
        + ("" if done == n_variants else " (the sweep was interrupted: run it again to finish it)")
        + "."
    )
    if spec.set:
        lines.append("Every variant with: " + ", ".join(f"`{k}={v}`" for k, v in spec.set.items()) + ".")
    lines.append("")
    if done == 0:
        return "\n".join(lines) + "\n"
    lines += ["| status | variants |", "| --- | --- |"]
    for status, count in frame["status"].value_counts().items():
        lines.append(f"| {status} | {count} |")
    metrics = plotted_metrics(frame, swept)
    for key in swept:
        lines += [
            "",
            f"## `{key}`",
            "",
            "| value | variants | success rate (95 % CI) | "
            + " | ".join(f"{m} mean (95 % CI)" for m in metrics)
            + " |",
            "| --- " * (3 + len(metrics)) + "|",
        ]
        for label, _, rows in groups(frame, key):
            k, n = _success(rows)
            lo, hi = wilson_interval(k, n)
            cells = [label, str(n), f"{k / n:.0%} [{lo:.0%}, {hi:.0%}]"]
            for m in metrics:
                mean, mlo, mhi = t_interval(rows[m].to_numpy(float))
                cells.append(f"{mean:.4g}" + ("" if math.isnan(mlo) else f" [{mlo:.4g}, {mhi:.4g}]"))
            lines.append("| " + " | ".join(cells) + " |")
    failed = frame[frame["status"] == FAILED]
    if len(failed):
        lines += ["", "## Failed variants", ""]
        for _, row in failed.iterrows():
            lines.append(f"- `{row['key']}` (" + ", ".join(f"{k}={row[k]}" for k in swept) + f"): {row['message']}")
    if images:
        lines += ["", "## Plots", ""] + [f"![{p.stem}]({p.relative_to(out)})" for p in images]
    return "\n".join(lines) + "\n"


def _plot(folder: Path, frame: Any, swept: list[str]) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    metrics = plotted_metrics(frame, swept)[:4]
    paths = []
    for key in swept:
        parts = groups(frame, key)
        pos = np.arange(len(parts), dtype=float)
        fig, axes = plt.subplots(
            1 + len(metrics),
            1,
            figsize=(max(5.0, 1.1 * len(parts) + 2), 2.6 * (1 + len(metrics))),
            sharex=True,
            squeeze=False,
        )
        ax = axes[0, 0]
        rates: list[float] = []
        err: list[list[float]] = [[], []]
        for _, _, rows in parts:
            k, n = _success(rows)
            lo, hi = wilson_interval(k, n)
            rates.append(k / n)
            err[0].append(k / n - lo)
            err[1].append(hi - k / n)
        ax.errorbar(pos, rates, yerr=err, fmt="o", capsize=4)
        ax.set_ylim(-0.05, 1.05)
        ax.set_ylabel("success rate")
        ax.set_title(f"{key}: 95 % CIs (Wilson; Student t)", fontsize=9)
        for i, m in enumerate(metrics, start=1):
            ax = axes[i, 0]
            for j, (_, _, rows) in enumerate(parts):
                v = rows[m].to_numpy(float)
                v = v[np.isfinite(v)]
                ax.scatter(
                    np.full(v.size, pos[j]) + np.linspace(-0.15, 0.15, v.size) if v.size else [],
                    v,
                    s=8,
                    alpha=0.4,
                    color="grey",
                )
                mean, lo, hi = t_interval(v)
                if math.isfinite(mean):
                    ax.errorbar(
                        [pos[j] + 0.25],
                        [mean],
                        yerr=None if math.isnan(lo) else [[mean - lo], [hi - mean]],
                        fmt="s",
                        color="C1",
                        capsize=4,
                    )
            ax.set_ylabel(m, fontsize=8)
        axes[-1, 0].set_xticks(pos, [p[0] for p in parts], rotation=30 if len(parts) > 4 else 0, fontsize=8)
        axes[-1, 0].set_xlabel(key)
        fig.tight_layout()
        path = folder / f"{key}.png"
        fig.savefig(path, dpi=90)
        plt.close(fig)
        paths.append(path)
    return paths
