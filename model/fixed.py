"""Fixed-point conversion between metres and the correlator's 16-bit depth words.

The correlator sees only integers; this is the one place where metres become words and back. The
rounding is explicit and every value that cannot be represented is an error, never a clipped word.
"""

from __future__ import annotations

import numpy as np

from .correlator import DEPTH_MAX, DEPTH_MIN

__all__ = ["ROUNDING_MODES", "quantize", "dequantize"]

# np.rint rounds half to even; floor and ceil are for callers that need a one-sided error.
ROUNDING_MODES = {"half_even": np.rint, "floor": np.floor, "ceil": np.ceil}


def quantize(
    depths_m: np.ndarray,
    lsb_m: float,
    *,
    offset_m: float = 0.0,
    rounding: str = "half_even",
) -> np.ndarray:
    """Turn depths in metres into 16-bit depth words: ``round((depth - offset_m) / lsb_m)``.

    Parameters
    ----------
    depths_m : array_like of float
        Depths (or heights) in metres; any shape.
    lsb_m : float
        Metres per word step, positive and finite (e.g. 0.1 for decimetre words).
    offset_m : float
        Depth that maps to word 0; choose it near the middle of the data to use the word's range.
    rounding : {"half_even", "floor", "ceil"}
        How a value between two steps becomes a word.

    Returns
    -------
    int16 array of the input's shape.

    Raises
    ------
    ValueError
        A NaN or infinite depth (with how many and where the first is), a word outside
        ``[-32768, 32767]`` (with the offending depth and the range that fits), a bad ``lsb_m`` or
        ``rounding``.
    """
    if rounding not in ROUNDING_MODES:
        raise ValueError(f"rounding must be one of {sorted(ROUNDING_MODES)}, got {rounding!r}")
    if not np.isfinite(lsb_m) or lsb_m <= 0:
        raise ValueError(f"lsb_m must be a positive finite number of metres, got {lsb_m!r}")
    if not np.isfinite(offset_m):
        raise ValueError(f"offset_m must be finite, got {offset_m!r}")
    depths = np.asarray(depths_m, dtype=np.float64)
    bad = ~np.isfinite(depths)
    if bad.any():
        first = tuple(int(x) for x in np.argwhere(bad)[0])
        raise ValueError(
            f"depths contain {int(bad.sum())} NaN or infinite value(s), the first at index {first}; "
            "mask them out before quantizing"
        )
    words = ROUNDING_MODES[rounding]((depths - offset_m) / lsb_m)
    over = (words < DEPTH_MIN) | (words > DEPTH_MAX)
    if over.any():
        first = tuple(int(x) for x in np.argwhere(over)[0])
        lo_m = offset_m + DEPTH_MIN * lsb_m
        hi_m = offset_m + DEPTH_MAX * lsb_m
        raise ValueError(
            f"{int(over.sum())} depth(s) overflow the 16-bit word, the first {depths[first]!r} m at "
            f"index {first}; with lsb_m={lsb_m} and offset_m={offset_m} the words hold "
            f"[{lo_m:.6g}, {hi_m:.6g}] m"
        )
    return words.astype(np.int16)


def dequantize(words: np.ndarray, lsb_m: float, *, offset_m: float = 0.0) -> np.ndarray:
    """Depth words back to metres (float64): ``offset_m + words * lsb_m``."""
    words = np.asarray(words)
    if words.dtype.kind not in "iu":
        raise ValueError(f"words must be an integer array, got dtype {words.dtype}")
    return offset_m + words.astype(np.float64) * lsb_m
