"""The README stays short and honest: at most 8,000 characters, its picture a real PNG in docs/assets, every link to
a file that exists, every speed figure one the benchmarks page carries (with its command), and its Table 1 the
tunnel case study's."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
README = (REPO / "README.md").read_text(encoding="utf-8")
BENCHMARKS = (REPO / "docs" / "benchmarks.md").read_text(encoding="utf-8")
TUNNEL = (REPO / "docs" / "case-studies" / "tunnel.md").read_text(encoding="utf-8")
LINK = re.compile(r"\]\((?P<target>[^)\s]+)\)")


def test_readme_is_at_most_8000_characters() -> None:
    assert len(README) <= 8000, len(README)


def test_readme_starts_with_the_two_commands() -> None:
    first_block = re.search(r"```sh\n(?P<code>.*?)```", README, re.S)
    assert first_block is not None
    assert first_block["code"].split() == ["make", "demo", "make", "test"]


def test_readme_links_and_picture_exist() -> None:
    targets = [m["target"] for m in LINK.finditer(README) if not re.match(r"[a-z]+://", m["target"])]
    assert len(targets) >= 20
    for target in targets:
        assert (REPO / target.split("#")[0]).exists(), target
    pictures = re.findall(r"!\[[^\]]*\]\((?P<target>[^)]+)\)", README)
    assert pictures and all(p.startswith("docs/assets/") and p.endswith(".png") for p in pictures), pictures
    for p in pictures:
        assert (REPO / p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", p


def test_every_speed_figure_is_on_the_benchmarks_page_with_its_command() -> None:
    figures = re.findall(r"\d[\d ]*(?:[.–]\d[\d ]*)*×", README)
    assert len(figures) >= 3, figures
    for figure in figures:
        assert figure in BENCHMARKS, f"README's {figure} is not on docs/benchmarks.md"
    for script in re.findall(r"benchmarks/bench_\w+\.py", README):
        assert script in BENCHMARKS, script
        assert (REPO / script).is_file(), script


def test_table_1_matches_the_tunnel_case_study() -> None:
    rows = re.findall(r"^\| (odometry|tracking) min / RMSE / max \| ([\d. /]+) \| ([\d. /]+) \|", README, re.M)
    assert len(rows) == 2, rows
    for name, paper, ours in rows:
        assert f"| {name} min / RMSE / max | {paper.strip()} | {ours.strip()} |" in TUNNEL, name
