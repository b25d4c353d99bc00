"""Client of the fork server and the shared hypothesis strategies of the fuzz suite."""

from __future__ import annotations

import collections
import json
import os
import pickle
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

HERE = Path(__file__).resolve().parent

#: Examples per fuzz test: small in the default run (CI: the whole suite in well under 2 minutes),
#: large in ``make fuzz`` (CUFUND_FUZZ_EXAMPLES=...).
EXAMPLES = int(os.environ.get("CUFUND_FUZZ_EXAMPLES", "12"))
#: Address-space cap of each case [bytes] (the issue's measurement used 6 GiB).
CAP = int(float(os.environ.get("CUFUND_FUZZ_CAP_GIB", "4")) * 2**30)
TIMEOUT = float(os.environ.get("CUFUND_FUZZ_TIMEOUT", "20"))

fuzz_settings = settings(
    max_examples=EXAMPLES,
    deadline=None,
    database=None,
    derandomize=EXAMPLES <= 50,  # the bounded CI run is reproducible; the long campaign explores
    suppress_health_check=list(HealthCheck),
)

# Every outcome, per area, for the closing table (see conftest.py).
STATS: dict[str, collections.Counter] = collections.defaultdict(collections.Counter)
FAILURES: list[tuple[str, str, str, str]] = []
GOOD = ("ok", "clean")
#: ``make fuzz`` (CUFUND_FUZZ_CAMPAIGN=1) records every outcome for the table instead of stopping at the first bad one.
CAMPAIGN = os.environ.get("CUFUND_FUZZ_CAMPAIGN") == "1"


def expect_good(outcome: str, detail: str) -> None:
    """The case ended well: returned a checked result, or raised a clean error naming what was wrong."""
    if not CAMPAIGN:
        assert outcome in GOOD, detail


class Code(str):
    """An argument given as Python source, evaluated in the child (e.g. a huge broadcast array)."""


class ForkServer:
    def __init__(self) -> None:
        env = {**os.environ, "PYTHONWARNINGS": "ignore"}
        self.proc = subprocess.Popen(
            [sys.executable, str(HERE / "forkserver.py")], stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env
        )

    def run(
        self,
        area: str,
        setup: str,
        call: str,
        args: dict[str, Any] | None = None,
        check: str | None = None,
        timeout: float = TIMEOUT,
    ) -> tuple[str, str]:
        wire = {k: ("__code__", str(v)) if isinstance(v, Code) else v for k, v in (args or {}).items()}
        data = pickle.dumps((setup, call, wire, check, timeout, CAP))
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(struct.pack("<Q", len(data)) + data)
        self.proc.stdin.flush()
        (n,) = struct.unpack("<Q", self.proc.stdout.read(8))
        outcome, detail, _ = pickle.loads(self.proc.stdout.read(n))
        STATS[area][outcome] += 1
        if outcome not in GOOD:
            FAILURES.append((area, outcome, f"{call} with {_short(args)}", detail))
        return outcome, detail

    def close(self) -> None:
        if self.proc.stdin:
            self.proc.stdin.close()
        self.proc.wait(timeout=30)
        if self.proc.stdout:
            self.proc.stdout.close()


def _short(args: dict[str, Any] | None) -> str:
    out = {}
    for k, v in (args or {}).items():
        if isinstance(v, np.ndarray):
            out[k] = f"ndarray{v.shape}:{v.dtype}" + (f"={v.ravel()[:6].tolist()}" if v.size else "")
        else:
            out[k] = v if len(repr(v)) < 120 else repr(v)[:120] + "..."
    return repr(out)


def write_report(path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(
        json.dumps(
            {"stats": {a: dict(c) for a, c in sorted(STATS.items())}, "failures": FAILURES[:200]}, indent=1, default=str
        )
    )


# --- strategies: what a user who makes mistakes types -----------------------------------------------


def floats_any() -> st.SearchStrategy[float]:
    """Any float64, with the edge cases made likely."""
    return st.one_of(
        st.sampled_from(
            [
                0.0,
                -0.0,
                1.0,
                -1.0,
                1e-300,
                5e-324,
                -5e-324,
                1e300,
                1e308,
                float("nan"),
                float("inf"),
                float("-inf"),
                1.5e16,
                2.0**31,
                2.0**53,
            ]
        ),
        st.floats(allow_nan=True, allow_infinity=True),
        st.floats(-1e3, 1e3),
    )


def scalars() -> st.SearchStrategy[Any]:
    """Wrong-typed and right-typed scalars."""
    return st.one_of(
        floats_any(),
        st.integers(-(2**70), 2**70),
        st.booleans(),
        st.none(),
        st.text(max_size=8),
        st.binary(max_size=4),
        st.just([]),
        st.just({}),
        st.just(np.float32(1.0)),
        st.just(np.int64(3)),
        st.just(np.nan),
        st.just(complex(1, 1)),
    )


def arrays(
    shapes: list[tuple[int, ...]] | None = None, elements: st.SearchStrategy[float] | None = None
) -> st.SearchStrategy[Any]:
    """Arrays of the right and wrong shapes and dtypes (small), plus non-arrays."""
    from hypothesis.extra import numpy as hnp

    shape = st.sampled_from(shapes) if shapes else hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=5)
    dtype = st.sampled_from([np.float64, np.float32, np.int64, np.int32, np.uint8, np.bool_, np.complex128])
    elems = elements if elements is not None else floats_any()

    @st.composite
    def make(draw: Any) -> Any:
        dt = draw(dtype)
        shp = draw(shape)
        if dt in (np.float64, np.float32):
            return draw(
                hnp.arrays(
                    dt,
                    shp,
                    elements=elems.map(lambda x: x if abs(x) < 1e37 or not np.isfinite(x) or dt is np.float64 else 0.0),
                )
            )
        if dt is np.complex128:
            return np.zeros(shp, dt)
        return draw(hnp.arrays(dt, shp))

    return st.one_of(
        make(), scalars(), st.lists(floats_any(), max_size=7), st.just("abc"), st.just(np.array([], object))
    )
