"""The one error type the command line maps to its usage exit code (2); every other input error exits 1."""

from __future__ import annotations

__all__ = ["UsageError"]


class UsageError(ValueError):
    """The options contradict each other or name nothing known: exit code 2, like argparse's own errors."""
