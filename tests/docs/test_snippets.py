"""Every code snippet of the documentation runs: the python blocks and the ``cufund ...`` shell blocks of
docs/**/*.md and README.md, in page order, in a fresh temporary directory per page.

- ``python`` blocks of one page share one namespace (a later block uses what an earlier one defined) and run under
  pytest's warning filters (``error``: a snippet on a deprecated module path fails).
- ``sh`` / ``bash`` / ``console`` blocks: every command in them must be a ``cufund ...`` command; each runs as a
  process (the venv's ``cufund``) and must exit 0, or the code a trailing ``# exits N`` comment states.
- a fenced block with ``title="NAME"`` (e.g. ```` ```yaml title="my_square.yaml" ````) is written to NAME in the
  page's directory before the blocks after it run: the YAML a page shows is the YAML its commands read.
- a block that must not run (a server that never returns, PX4's own build, ``make test``) carries the marker
  ``<!-- no-run: REASON -->`` on the line before it. Such blocks are few and each says why.
"""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
import textwrap
import types
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
PAGES = sorted([*DOCS.rglob("*.md"), REPO / "README.md"])
CUFUND = Path(sys.executable).with_name("cufund")

PYTHON = {"python", "py", "pycon"}
SHELL = {"sh", "bash", "console", "shell"}
NO_RUN = re.compile(r"^\s*<!--\s*no-run:\s*(?P<reason>.*?)\s*-->\s*$")
FENCE = re.compile(r"^(?P<indent>\s*)(?P<fence>`{3,}|~{3,})(?P<info>.*)$")
EXITS = re.compile(r"#\s*exits\s+(?P<code>\d+)\s*$")
MAX_NO_RUN = 12
"""The marker is for the few blocks that cannot run here; more than this many means it is being used to hide
snippets that fail."""


@dataclass(frozen=True)
class Block:
    page: Path
    line: int  # 1-based line of the opening fence
    lang: str
    title: str | None
    code: str
    no_run: str | None  # the marker's reason, or None

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(REPO) if self.page.is_relative_to(REPO) else self.page}:{self.line}"


def blocks(page: Path, text: str | None = None) -> list[Block]:
    """The fenced code blocks of a Markdown page, with their language, title and no-run marker."""
    lines = (page.read_text(encoding="utf-8") if text is None else text).splitlines()
    out: list[Block] = []
    i = 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent, fence, info = m["indent"], m["fence"], m["info"].strip()
        start = i
        body: list[str] = []
        i += 1
        while i < len(lines) and not (lines[i].strip().startswith(fence) and lines[i].strip().strip(fence[0]) == ""):
            body.append(lines[i][len(indent) :] if lines[i].startswith(indent) else lines[i].lstrip())
            i += 1
        if i == len(lines):
            raise AssertionError(f"{page}:{start + 1}: a code fence is never closed")
        i += 1
        lang = info.split()[0].lstrip(".").lower() if info else ""
        title = re.search(r'title="([^"]+)"', info)
        prev = start - 1
        while prev >= 0 and not lines[prev].strip():
            prev -= 1
        marker = NO_RUN.match(lines[prev]) if prev >= 0 else None
        out.append(
            Block(
                page,
                start + 1,
                lang,
                title[1] if title else None,
                textwrap.dedent("\n".join(body)) + "\n",
                marker["reason"] if marker else None,
            )
        )
    return out


def shell_commands(block: Block) -> list[tuple[list[str], int]]:
    """The commands of a shell block with the exit code each must give; anything but ``cufund ...`` is an error
    (mark such a block no-run)."""
    commands = []
    for logical in block.code.replace("\\\n", " ").splitlines():
        stripped = logical.strip()
        if not stripped or stripped.startswith("#"):
            continue
        if stripped.startswith("$ "):
            stripped = stripped[2:]
        expected = EXITS.search(stripped)
        argv = shlex.split(stripped, comments=True)
        if not argv or argv[0] != "cufund":
            raise AssertionError(
                f"{block.where}: only `cufund ...` commands run in a shell block, got {stripped!r}; "
                "mark the block <!-- no-run: REASON --> if it must not run"
            )
        commands.append((argv, int(expected["code"]) if expected else 0))
    return commands


def run_page(page_blocks: list[Block], workdir: Path) -> int:
    """Runs a page's blocks in order in ``workdir``; returns how many ran. Raises AssertionError naming the block
    and its output on the first failure."""
    module = types.ModuleType(f"cufund_docs_{abs(hash(page_blocks[0].page)) if page_blocks else 0}")
    namespace = module.__dict__  # a real module, so that dataclasses and pickling find the snippets' classes
    sys.modules[module.__name__] = module
    env = dict(os.environ, PATH=f"{CUFUND.parent}{os.pathsep}{os.environ.get('PATH', '')}", MPLBACKEND="Agg")
    ran = 0
    cwd = os.getcwd()
    os.chdir(workdir)
    try:
        for block in page_blocks:
            if block.no_run is not None:
                continue
            if block.title is not None:
                (workdir / block.title).parent.mkdir(parents=True, exist_ok=True)
                (workdir / block.title).write_text(block.code, encoding="utf-8")
            if block.lang in PYTHON:
                try:
                    exec(compile(block.code, block.where, "exec"), namespace)
                except Exception as e:
                    raise AssertionError(f"{block.where}: the python block raised {type(e).__name__}: {e}") from e
                ran += 1
            elif block.lang in SHELL:
                for argv, expected in shell_commands(block):
                    exe = [str(CUFUND) if CUFUND.exists() else "cufund", *argv[1:]]
                    done = subprocess.run(
                        exe, cwd=workdir, env=env, capture_output=True, text=True, timeout=600, check=False
                    )
                    if done.returncode != expected:
                        raise AssertionError(
                            f"{block.where}: `{shlex.join(argv)}` exited {done.returncode}, expected {expected}\n"
                            f"stdout:\n{done.stdout[-3000:]}\nstderr:\n{done.stderr[-3000:]}"
                        )
                    ran += 1
    finally:
        os.chdir(cwd)
        sys.modules.pop(module.__name__, None)
    return ran


def _id(page: Path) -> str:
    return str(page.relative_to(REPO))


RUNNABLE = [p for p in PAGES if any(b.no_run is None and (b.lang in PYTHON | SHELL) for b in blocks(p))]


@pytest.fixture
def registry_restored():
    """A page's snippets may register kinds (the custom-kinds guide does): the registry is as it was afterwards, so
    the pages leave nothing behind for the tests that run after them in this process."""
    from cufund.core import registry

    registry.load_plugins()
    kinds = {group: dict(table) for group, table in registry._KINDS.items()}
    sensor_types = dict(registry._SENSOR_TYPES)
    yield
    for group, table in kinds.items():
        registry._KINDS[group].clear()
        registry._KINDS[group].update(table)
    registry._SENSOR_TYPES.clear()
    registry._SENSOR_TYPES.update(sensor_types)


@pytest.mark.parametrize("page", RUNNABLE, ids=_id)
def test_page_snippets_run(page: Path, tmp_path: Path, registry_restored) -> None:
    assert run_page(blocks(page), tmp_path) > 0


def test_no_run_markers_are_few_and_give_a_reason() -> None:
    marked = [b for p in PAGES for b in blocks(p) if b.no_run is not None]
    assert all(b.no_run for b in marked), [b.where for b in marked if not b.no_run]
    assert len(marked) <= MAX_NO_RUN, [f"{b.where}: {b.no_run}" for b in marked]


def test_every_marker_stands_before_a_code_block() -> None:
    for page in PAGES:
        lines = page.read_text(encoding="utf-8").splitlines()
        for n, line in enumerate(lines):
            if NO_RUN.match(line):
                following = next((x for x in lines[n + 1 :] if x.strip()), "")
                assert FENCE.match(following), f"{_id(page)}:{n + 1}: a no-run marker that marks no code block"


def test_the_docs_have_runnable_snippets() -> None:
    """The checks above would pass vacuously on a docs folder without code."""
    assert len(RUNNABLE) >= 10, [_id(p) for p in RUNNABLE]


# The runner must be able to fail: a page whose snippet is wrong, in each kind of block.
@pytest.mark.parametrize(
    "text, message",
    [
        ("```python\nx = 1\n```\n\n```python\nassert x == 2, 'x is 1'\n```\n", "AssertionError: x is 1"),
        (
            "```python\nimport sys\nsys.modules.pop('cufund.bus', None)\nimport cufund.bus\n```\n",
            "moved to cufund.core.bus",
        ),
        ("```sh\ncufund run no_such_scenario\n```\n", "exited 2, expected 0"),
        ("```sh\ncufund --version  # exits 1\n```\n", "exited 0, expected 1"),
        ("```sh\nmake demo\n```\n", "only `cufund ...` commands run"),
    ],
)
def test_a_wrong_snippet_fails(text: str, message: str, tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text(text, encoding="utf-8")
    work = tmp_path / "work"
    work.mkdir()
    with pytest.raises(AssertionError, match=re.escape(message)):
        run_page(blocks(page), work)


def test_titled_blocks_are_written_and_marked_blocks_skipped(tmp_path: Path) -> None:
    text = (
        '```yaml title="a/b.yaml"\nkey: 1\n```\n\n<!-- no-run: a server -->\n```python\nraise SystemExit\n```\n\n'
        "```python\nfrom pathlib import Path\nassert Path('a/b.yaml').read_text() == 'key: 1\\n'\n```\n"
    )
    page = tmp_path / "page.md"
    page.write_text(text, encoding="utf-8")
    found = blocks(page)
    assert [b.no_run for b in found] == [None, "a server", None]
    work = tmp_path / "work"
    work.mkdir()
    assert run_page(found, work) == 1
