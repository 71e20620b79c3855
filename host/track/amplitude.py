"""Detection strength as evidence: the amplitude likelihood ratio of integrated PDA with amplitude information.

A detector that reports each detection's strength says more than where it is: a contact's echoes are on
the whole stronger than the clutter that crosses the same threshold. Lerro & Bar-Shalom ("Interacting
multiple model tracking with target amplitude feature", IEEE Trans. AES 29(2), 1993) weigh each
detection's association by the ratio of the two strength densities; the same ratio enters integrated
PDA's existence update (IPDA with amplitude information). Here the ratio multiplies the spatial density of detection ``j`` about track ``t`` in the
joint association (:mod:`.association`), so a strong return raises a track's existence faster and a weak
one less, while a missed ping weighs as before (``pd`` is already the probability of crossing the
threshold).

The tracker's model is the simplest that can be fitted from a log: strength in dB Gaussian for a contact
(``target_strength_db`` +/- ``target_strength_sigma_db``) and for clutter (``clutter_strength_db`` +/-
``clutter_strength_sigma_db``). A Gaussian's tails are where such a fit is worst (a real clutter spike is
more likely than the fit says), so the ratio is clipped to ``[1 / max_amplitude_ratio, max_amplitude_ratio]``:
one detection's strength changes a track's odds by at most that factor. A detection without a strength
(NaN) weighs 1, as does every detection when ``amplitude`` is off.

A log whose strengths are on another scale (dB re 1 uPa rather than dB above the threshold, say) would
make every ratio the clip's: :func:`check_strength_scale` refuses it by name.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .detections import Ping

__all__ = ["amplitude_ratio", "check_strength_scale", "StrengthScaleError"]

#: Fewer strengths than this say too little about their scale to refuse a log on it.
_MIN_STRENGTHS = 20


class StrengthScaleError(ValueError):
    """The detections' strengths are not on the scale the tracker's amplitude model assumes."""


def amplitude_ratio(strength_db: np.ndarray, parameters) -> np.ndarray:
    """Likelihood ratio contact/clutter of each strength (dB) under ``parameters``' Gaussian model, clipped; 1 where NaN.

    ``parameters`` is a :class:`~.tracker.TrackerParameters` (its ``amplitude``, ``target_strength_db``,
    ``target_strength_sigma_db``, ``clutter_strength_db``, ``clutter_strength_sigma_db``, ``max_amplitude_ratio``).
    """
    s = np.asarray(strength_db, dtype=float)
    ratio = np.ones(s.shape)
    known = np.isfinite(s)
    if not parameters.amplitude or not known.any():
        return ratio
    p = parameters
    z_target = (s[known] - p.target_strength_db) / p.target_strength_sigma_db
    z_clutter = (s[known] - p.clutter_strength_db) / p.clutter_strength_sigma_db
    log_ratio = 0.5 * (z_clutter**2 - z_target**2) + math.log(p.clutter_strength_sigma_db / p.target_strength_sigma_db)
    limit = math.log(p.max_amplitude_ratio)
    ratio[known] = np.exp(np.clip(log_ratio, -limit, limit))
    return ratio


def check_strength_scale(pings: Sequence[Ping], parameters) -> None:
    """Refuse strengths that cannot be on the model's scale: their median beyond three sigmas of both densities.

    Most detections of a log are clutter, so the median strength lies near the clutter's (or, with few false
    alarms, the contacts'). Logs with fewer than 20 strengths, or with ``amplitude`` off, are not judged.

    Raises
    ------
    StrengthScaleError
        Naming the median found, the model's scale, and the two ways out.
    """
    if not parameters.amplitude:
        return
    strengths = np.concatenate([np.asarray(p.strength_db, float) for p in pings]) if pings else np.empty(0)
    strengths = strengths[np.isfinite(strengths)]
    if strengths.size < _MIN_STRENGTHS:
        return
    p, median = parameters, float(np.median(strengths))
    low = min(p.clutter_strength_db - 3 * p.clutter_strength_sigma_db, p.target_strength_db - 3 * p.target_strength_sigma_db)
    high = max(p.clutter_strength_db + 3 * p.clutter_strength_sigma_db, p.target_strength_db + 3 * p.target_strength_sigma_db)
    if not low <= median <= high:
        raise StrengthScaleError(
            f"strength_db: the median detection strength is {median:.3g} dB, outside [{low:.3g}, {high:.3g}] dB that the tracker's "
            f"amplitude model allows (clutter {p.clutter_strength_db:g} +/- {p.clutter_strength_sigma_db:g} dB, contacts "
            f"{p.target_strength_db:g} +/- {p.target_strength_sigma_db:g} dB above the detection threshold); give your detector's "
            "model (--set clutter_strength_db=... --set clutter_strength_sigma_db=... --set target_strength_db=... "
            "--set target_strength_sigma_db=...) or --set amplitude=false to track without the strengths")
