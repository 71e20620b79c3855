"""Map and patch shapes as people type them: ``ROWSxCOLS`` (``501x501``, ``10x10``).

One parser for every command line of the project (``lost run --patch-shape``, ``make verilog``,
``make cycles``), so they accept and refuse the same spellings.
"""

from __future__ import annotations

import argparse

__all__ = ["shape_argument"]


def shape_argument(text: str) -> tuple[int, int]:
    """``"ROWSxCOLS"`` as ``(rows, cols)``, both positive; an ``argparse`` type (its error is the message shown)."""
    rows, sep, cols = text.strip().lower().partition("x")
    try:
        shape = (int(rows), int(cols))
    except ValueError:
        shape = None
    if not sep or shape is None or min(shape) < 1:
        raise argparse.ArgumentTypeError(f"expected ROWSxCOLS with two positive integers, such as 501x501, got {text!r}")
    return shape
