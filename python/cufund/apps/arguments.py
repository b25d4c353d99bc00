"""Command-line arguments several of cufund's commands share."""

from __future__ import annotations

import argparse

__all__ = ["add_overrides"]


def add_overrides(
    p: argparse.ArgumentParser, help: str = "override a scenario field by its dotted key (repeatable)"
) -> None:
    """``--set KEY=VALUE`` (repeatable) into ``args.overrides``: a scenario field by its dotted key."""
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE", help=help)
