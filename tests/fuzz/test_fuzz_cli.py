"""Fuzz: ``cufund run`` on mutated scenario files and overrides. Exit 0 (completed) or 1 (ended otherwise) when
the configuration is valid, 2 with a one-line message and no traceback when it is not; never a crash or hang."""

from __future__ import annotations

import copy
from pathlib import Path

import yaml
from fuzz_support import EXAMPLES, expect_good, fuzz_settings
from hypothesis import given, settings
from hypothesis import strategies as st

import cufund

SQUARE = yaml.safe_load((Path(cufund.__file__).parent / "scenarios" / "builtin" / "square.yaml").read_text())
ATOMS = [
    "1",
    "-1",
    "0",
    ".nan",
    ".inf",
    "1e400",
    "1e-320",
    "true",
    "null",
    "x",
    "[]",
    "{}",
    "[1, 2]",
    "[1, 2, 3]",
    "{kind: nope}",
    "geometric",
    "'1e3'",
    "300",
    "1e9",
    "-.inf",
]

# The child runs cufund's CLI in-process with stderr captured and classifies the exit itself.
RUN = """
import contextlib, io, os
from cufund.apps import cli
os.chdir(cwd)  # a relative or empty --out lands in the case's folder, never in the source tree
err = io.StringIO()
with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
    try:
        code = cli.main(argv)
    except SystemExit as e:
        code = e.code
text = err.getvalue()
if code == 2 and ("Traceback" in text or not text.strip()):
    raise RuntimeError("exit 2 without a clean one-line message: " + text[-300:])
if code == 2:
    raise ValueError(text.strip()[-300:])  # a clean configuration error
result = code
"""


def _paths(d: object, prefix: str = "") -> list[str]:
    out = []
    if isinstance(d, dict):
        for k, v in d.items():
            out.append(prefix + str(k))
            out += _paths(v, prefix + str(k) + ".")
    return out


PATHS = _paths(SQUARE)


def _mutate(path: str, atom: str | None) -> dict:
    data = copy.deepcopy(SQUARE)
    node = data
    keys = path.split(".")
    for k in keys[:-1]:
        node = node[k]
    if atom is None:
        node.pop(keys[-1], None)
    else:
        node[keys[-1]] = yaml.safe_load(atom) if atom != "x" else "x"
    return data


# A case that flies costs seconds: the default run tries a few, the campaign its full count.
cli_settings = settings(fuzz_settings, max_examples=EXAMPLES if EXAMPLES > 50 else 4)


@cli_settings
@given(
    path=st.sampled_from(PATHS + ["unknown_key", "controller.unknown", "trajectory.extra"]),
    atom=st.one_of(st.none(), st.sampled_from(ATOMS)),
    override=st.one_of(st.none(), st.tuples(st.sampled_from(PATHS + ["nope.key", ""]), st.sampled_from(ATOMS))),
)
def test_cufund_run(server, tmp_path_factory, path, atom, override):
    folder = tmp_path_factory.mktemp("cli")
    scenario = folder / "scenario.yaml"
    data = _mutate(path, atom)
    scenario.write_text(yaml.safe_dump(data))
    argv = ["run", str(scenario), "--out", str(folder / "run"), "--no-replay", "--no-log"]
    if override is not None:
        argv += ["--set", f"{override[0]}={override[1]}"]
    if path != "duration" and (override is None or override[0] != "duration"):
        argv += ["--set", "duration=0.3"]  # a valid mutation flies briefly, not 40 s
    outcome, detail = server.run(
        "cli", "", RUN, {"argv": argv, "cwd": str(folder)}, check="result in (0, 1)", timeout=120
    )
    expect_good(outcome, detail)


@cli_settings
@given(
    out=st.sampled_from(["", "/proc/nope/run", "/dev/null", "scenario.yaml", "/", "a\x00b"]),
    extra=st.sampled_from(
        [
            [],
            ["--seed", "x"],
            ["--seed", "-1"],
            ["--controller", "nope"],
            ["--set", "noequals"],
            ["--set", "=3"],
            ["--bogus"],
        ]
    ),
)
def test_cufund_run_arguments(server, tmp_path_factory, out, extra):
    folder = tmp_path_factory.mktemp("cliargs")
    (folder / "scenario.yaml").write_text(yaml.safe_dump(SQUARE))
    out_path = out if out.startswith("/") or not out else str(folder / out)
    argv = [
        "run",
        str(folder / "scenario.yaml"),
        "--out",
        out_path,
        "--no-replay",
        "--no-log",
        "--set",
        "duration=0.3",
        *extra,
    ]
    outcome, detail = server.run(
        "cli", "", RUN, {"argv": argv, "cwd": str(folder)}, check="result in (0, 1)", timeout=120
    )
    expect_good(outcome, detail)
