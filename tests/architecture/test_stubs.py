"""The checked-in type stubs are exactly what pybind11-stubgen generates from the compiled module."""

import subprocess
import sys
from pathlib import Path

STUB_DIR = Path(__file__).resolve().parents[2] / "python" / "cufund" / "_core"


def test_stubs_match_the_bindings(tmp_path):
    subprocess.run(
        [sys.executable, "-m", "pybind11_stubgen", "cufund._core", "-o", str(tmp_path), "--numpy-array-use-type-var"],
        check=True,
        capture_output=True,
    )
    generated = {
        p.relative_to(tmp_path / "cufund" / "_core"): p.read_text()
        for p in (tmp_path / "cufund" / "_core").rglob("*.pyi")
    }
    checked_in = {p.relative_to(STUB_DIR): p.read_text() for p in STUB_DIR.rglob("*.pyi")}
    assert sorted(generated) == sorted(checked_in), "stub files differ: run `make stubs`"
    for name, text in generated.items():
        assert checked_in[name] == text, f"{name} is stale: run `make stubs`"
