"""The fast software correlator: the golden model's integers, from a SIMD and OpenMP C kernel.

``lost.host._sad`` (``host/_sad.c``) computes every term in 32-bit lanes. That is exact only while
a sum of terms fits 32 unsigned bits, so this wrapper takes the bounds from
:func:`lost.model.correlator_widths` and hands the kernel the number of terms it may add before
spilling into the int64 output.
"""

from __future__ import annotations

import functools
import os

import numpy as np

from lost.model import correlator_widths

# libgomp reads this once, when the kernel loads it. Its default spins idle threads for a while; on
# a busy 2-core machine a spinning or parked team member made a 1 ms correlation take 16 ms.
# Sleeping at once costs a futex wake-up per call instead. A user's own setting wins.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

from .. import _sad  # noqa: E402  (after the environment is set)

__all__ = ["KERNEL", "software_surface"]

#: The instruction set the kernel dispatched to on this machine ("avx512", "avx2" or "generic").
KERNEL: str = _sad.KERNEL

_LANE_MAX = 2**32 - 1


@functools.lru_cache(maxsize=256)
def _terms_per_chunk(h: int, w: int, mean_compensation: bool) -> int:
    """How many terms the 32-bit lane accumulator adds exactly before spilling to int64 (kept per shape: a swath record
    asks nine times for the same one, and the bounds cost more than a small correlation)."""
    widths = correlator_widths(h, w)
    if widths.abs_term.hi >= 2**31:
        raise ValueError(f"a {h} x {w} patch is too large for the software correlator's 32-bit terms")
    total = widths.surface if mean_compensation else widths.surface_plain
    if total.hi <= _LANE_MAX:
        return h * w
    term = widths.abs_term if mean_compensation else widths.abs_difference
    return _LANE_MAX // term.hi


def software_surface(terrain: np.ndarray, patch: np.ndarray, mask: np.ndarray, mean_compensation: bool) -> np.ndarray:
    """Correlation surface of already-validated int16 terrain and patch and bool mask."""
    (H, W), (h, w) = terrain.shape, patch.shape
    chunk = _terms_per_chunk(h, w, mean_compensation)
    out = np.empty((H - h + 1, W - w + 1), dtype=np.int64)
    _sad.surface(
        np.ascontiguousarray(terrain, dtype=np.int16),
        np.ascontiguousarray(patch, dtype=np.int16),
        np.ascontiguousarray(mask, dtype=np.uint8),
        H,
        W,
        h,
        w,
        bool(mean_compensation),
        chunk,
        out,
    )
    return out
