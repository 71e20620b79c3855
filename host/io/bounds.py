"""A bounds window (west, south, east, north) checked, and cut from monotonic coordinates."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _check_bounds(bounds) -> tuple[float, float, float, float]:
    try:
        west, south, east, north = (float(v) for v in bounds)
    except (TypeError, ValueError):
        raise ValueError(f"bounds must be four numbers (west, south, east, north), got {bounds!r}") from None
    if not (np.all(np.isfinite([west, south, east, north])) and west < east and south < north):
        raise ValueError(f"bounds must be finite with west < east and south < north, got {bounds!r}")
    return west, south, east, north


def _window(coords: np.ndarray, lo: float, hi: float, path: Path, axis: str) -> slice:
    """The contiguous index range of monotonic coordinates inside [lo, hi]."""
    inside = np.flatnonzero((coords >= lo) & (coords <= hi))
    if inside.size < 2:
        raise ValueError(
            f"{path.name}: bounds {lo:g} to {hi:g} hold {inside.size} node(s) of {axis}, whose values run "
            f"{coords.min():g} to {coords.max():g}; a grid needs at least 2"
        )
    return slice(int(inside[0]), int(inside[-1]) + 1)

