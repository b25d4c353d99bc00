"""Placeholder while this command is being built in this session (replaced by its implementation)."""

from __future__ import annotations

import argparse


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", nargs="?", default=None)


def run(args: argparse.Namespace) -> int:
    raise SystemExit("cufund: this command is not built yet")
