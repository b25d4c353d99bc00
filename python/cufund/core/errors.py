"""The exception types cufund raises for bad input (one per kind of failure)."""

from __future__ import annotations

__all__ = ["ConfigError"]


class ConfigError(ValueError):
    """A configuration value or key is wrong; the message names the field and what was expected."""
