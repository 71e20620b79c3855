"""Our own yardstick, the one Stone Soup has no name for: when a filter locks on (NEES is ``lost.host.consistency``'s).

Lock, precisely: the filter has locked at ping ``k`` (1-based) when its estimate is within ``radius_m`` of
the target at ping ``k`` and at every later ping at which the target is in the sector; ``pings_to_lock`` is
that ``k`` (the paper's "fewer than 15 pings"). A filter that never does has no lock (``None``).
"""

from __future__ import annotations

import numpy as np

__all__ = ["LOCK_RADIUS_M", "pings_to_lock"]

#: An estimate this close to the diver counts as locked on (a few bearing sigmas at 450 m, far from the next clutter).
LOCK_RADIUS_M = 25.0


def pings_to_lock(errors_m: np.ndarray, valid: np.ndarray, *, radius_m: float = LOCK_RADIUS_M) -> int | None:
    """Pings until the estimate is within ``radius_m`` for good (module docstring); NaN errors count as outside.

    Parameters
    ----------
    errors_m : ndarray, shape (pings,)
        Distance of the estimate from the target at each ping.
    valid : ndarray of bool, shape (pings,)
        Pings at which the target is in the sector (the others are not judged).
    """
    errors_m, valid = np.asarray(errors_m, float), np.asarray(valid, bool)
    inside = np.isfinite(errors_m) & (errors_m <= radius_m)
    judged = np.flatnonzero(valid)
    if judged.size == 0:
        return None
    outside = judged[~inside[judged]]
    first = judged[0] if outside.size == 0 else outside[-1] + 1
    later = judged[judged >= first]
    return int(later[0]) + 1 if later.size else None


