"""Fuzz suite (issue 11): hypothesis drives every binding and loader, each case in its own forked process
under an address-space cap (forkserver.py). ``make fuzz`` runs the long campaign and prints the table."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from fuzz_support import CAMPAIGN, FAILURES, GOOD, STATS, ForkServer, write_report


@pytest.fixture(scope="session")
def server():
    s = ForkServer()
    yield s
    s.close()


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if not STATS:
        return
    tr = terminalreporter
    tr.section("cufund fuzz: outcomes per area")
    cols = ["ok", "clean", "generic", "wrong_type", "garbage", "crash", "hang", "setup_error"]
    tr.write_line(f"{'area':<14}{'inputs':>8}" + "".join(f"{c:>12}" for c in cols))
    for area, c in sorted(STATS.items()):
        tr.write_line(f"{area:<14}{sum(c.values()):>8}" + "".join(f"{c.get(k, 0):>12}" for k in cols))
    for area, outcome, case, detail in FAILURES[:20]:
        tr.write_line(f"  {area} {outcome}: {case[:160]} -> {detail[:200]}")
    report = os.environ.get("CUFUND_FUZZ_REPORT")
    if report:
        write_report(Path(report))


def pytest_sessionfinish(session, exitstatus):
    # A campaign records instead of asserting; it still fails when any case ended badly.
    if CAMPAIGN and any(k not in GOOD for c in STATS.values() for k in c):
        session.exitstatus = 1
