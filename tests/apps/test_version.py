"""``cufund --version`` prints ``cufund <version>``: the version the installed distribution declares
(``importlib.metadata``, i.e. pyproject.toml), which is also ``cufund.__version__`` (compiled into the extension)."""

from __future__ import annotations

import importlib.metadata
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import cufund
from cufund.apps import cli


def test_version_matches_the_distribution_metadata() -> None:
    assert cufund.__version__ == importlib.metadata.version("cufund")
    assert re.fullmatch(r"\d+\.\d+\.\d+(\S*)", cufund.__version__), cufund.__version__


def test_version_flag_prints_name_and_version_and_exits_0(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        cli.main(["--version"])
    assert exit_info.value.code == 0
    out = capsys.readouterr()
    assert out.out == f"cufund {importlib.metadata.version('cufund')}\n"
    assert out.err == ""


def test_console_script_prints_the_version() -> None:
    """The entry point a user types, in its own process (no subcommand needed)."""
    exe = Path(sys.executable).with_name("cufund")
    command = [str(exe)] if exe.exists() else [shutil.which("cufund") or "cufund"]
    done = subprocess.run([*command, "--version"], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == f"cufund {importlib.metadata.version('cufund')}"


def test_a_subcommand_is_still_required_without_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        cli.main([])
    assert exit_info.value.code == cli.EXIT_INVALID
    assert "required" in capsys.readouterr().err


def test_citation_names_the_version_and_license_the_package_declares() -> None:
    """CITATION.cff (read as YAML) cites the version ``cufund --version`` prints, under pyproject's licence."""
    import tomllib

    import yaml

    root = Path(__file__).resolve().parents[2]
    citation = yaml.safe_load((root / "CITATION.cff").read_text(encoding="utf-8"))
    project = tomllib.loads((root / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    assert citation["cff-version"] == "1.2.0"
    assert str(citation["version"]) == project["version"] == importlib.metadata.version("cufund")
    assert citation["license"] == project["license"]["text"] == "BSD-3-Clause"
    assert "BSD 3-Clause License" in (root / "LICENSE").read_text(encoding="utf-8")
