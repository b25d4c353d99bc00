"""A sweep's records on disk and its results table.

Each finished variant leaves ``variants/<key>/``: its run folder's files and ``result.json`` (written last, by an
atomic rename, so a variant cut short leaves no record and is run again on resume).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

from .execute import Outcome

__all__ = ["WALL_METRICS", "flatten", "is_wall_metric", "load_records", "results_frame", "write_record"]

WALL_METRICS = ("wall_time_s", "real_time_factor", "component_seconds", "variant_wall_s")
"""Metrics that measure the machine, not the flight: they differ between two runs of one configuration."""

FAILED = "failed"


def is_wall_metric(name: str) -> bool:
    return any(name == w or name.startswith(w + ".") for w in WALL_METRICS)


def flatten(metrics: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested metrics as dotted columns: ``{"a": {"b": 1}, "w": [3, 4]}`` -> ``{"a.b": 1, "w.0": 3, "w.1": 4}``."""
    out: dict[str, Any] = {}
    for k, v in metrics.items():
        name = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(flatten(v, name + "."))
        elif isinstance(v, (list, tuple)):
            out.update(flatten({str(i): x for i, x in enumerate(v)}, name + "."))
        else:
            out[name] = v
    return out


def _json_safe(x: Any) -> Any:
    if isinstance(x, float) and not math.isfinite(x):
        return None if math.isnan(x) else ("inf" if x > 0 else "-inf")
    if isinstance(x, dict):
        return {str(k): _json_safe(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json_safe(v) for v in x]
    return x


def write_record(out: Path, variant: Any, outcome: Outcome) -> dict[str, Any]:
    """Writes the variant's files and its ``result.json``; returns the record."""
    folder = out / "variants" / variant.key
    folder.mkdir(parents=True, exist_ok=True)
    for name, data in outcome.files.items():
        (folder / name).write_bytes(data)
    record = {
        "key": variant.key,
        "overrides": variant.overrides,
        "repeat": variant.repeat,
        "status": outcome.status,
        "message": outcome.message,
        "metrics": outcome.metrics,
        "variant_wall_s": outcome.variant_wall_s,
        "attempts": outcome.attempts,
        "worker": outcome.worker,
    }
    tmp = folder / "result.json.tmp"
    tmp.write_text(json.dumps(_json_safe(record), indent=1) + "\n", encoding="utf-8")
    os.replace(tmp, folder / "result.json")
    return record


def load_records(out: Path | None) -> dict[str, dict[str, Any]]:
    """The records already in ``out`` that finished (a run with any status; not ``failed``), by key."""
    records: dict[str, dict[str, Any]] = {}
    if out is None or not (out / "variants").is_dir():
        return records
    for path in sorted((out / "variants").glob("*/result.json")):
        try:
            record = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue  # unreadable: the variant runs again
        if isinstance(record, dict) and record.get("key") == path.parent.name and record.get("status") != FAILED:
            records[record["key"]] = record
    return records


def results_frame(
    variants: list[Any], records: dict[str, dict[str, Any]], swept_keys: list[str], repeats: int, out: Path | None
) -> Any:
    """One row per variant (in sweep order) that has a record: a column per swept key, ``repeat`` when repeated,
    ``key``, every metric (flattened, dotted), then ``status``, ``message``, ``variant_wall_s``, ``attempts`` and
    ``run_folder``."""
    import pandas as pd

    rows = []
    for v in variants:
        rec = records.get(v.key)
        if rec is None:
            continue
        row: dict[str, Any] = {k: v.overrides.get(k) for k in swept_keys}
        if repeats > 1:
            row["repeat"] = v.repeat
        row["key"] = v.key
        metrics = flatten({k: m for k, m in rec.get("metrics", {}).items() if k not in ("status", "message")})
        row.update(metrics)
        row.update(
            status=rec["status"], message=rec["message"], variant_wall_s=rec["variant_wall_s"], attempts=rec["attempts"]
        )
        row["run_folder"] = str(out / "variants" / v.key) if out is not None and rec["status"] != FAILED else None
        rows.append(row)
    frame = pd.DataFrame(rows)
    for name in frame.columns:  # None -> NaN in numeric columns; mixed columns as text (parquet needs one type)
        col = frame[name]
        if col.dtype == object:
            kinds = {type(x) for x in col if x is not None and not (isinstance(x, float) and math.isnan(x))}
            if kinds and kinds <= {int, float}:
                frame[name] = pd.to_numeric(col)
            elif len(kinds) > 1:
                frame[name] = col.map(lambda x: None if x is None else str(x))
    return frame
