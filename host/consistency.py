"""Filter consistency against the truth: the NEES of every estimate and its chi-square band, for every system.

The navigation filters (2 degrees of freedom, horizontal), the INS+USBL filter (3) and the tracker's estimates
(2) all report the normalized estimation error squared ``e' P^-1 e`` here, with the share of epochs inside the
central chi-square interval of ``dof`` degrees of freedom (95 % by default).
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

__all__ = ["nees", "nees_band", "three_sigma", "nees_figures", "BAND_PROBABILITY"]

#: The NEES band: the central interval of the chi-square distribution with this probability.
BAND_PROBABILITY = 0.95


def nees(error: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """``e' P^-1 e`` of each row of ``error`` (n, d) against ``covariance`` (n, d, d); NaN where either is not finite.

    A singular covariance (a filter that claims certainty) is inverted by its pseudo-inverse, so its NEES is large
    rather than an error.
    """
    error = np.asarray(error, dtype=np.float64)
    covariance = np.asarray(covariance, dtype=np.float64)
    out = np.full(len(error), np.nan)
    ok = np.isfinite(error).all(axis=1) & np.isfinite(covariance).all(axis=(1, 2))
    if ok.any():
        out[ok] = np.einsum("ni,nij,nj->n", error[ok], np.linalg.pinv(covariance[ok]), error[ok])
    return out


def nees_band(dof: int, probability: float = BAND_PROBABILITY) -> tuple[float, float]:
    """The central chi-square interval of ``dof`` degrees of freedom holding ``probability`` of the mass."""
    low, high = chi2.ppf([(1 - probability) / 2, (1 + probability) / 2], dof)
    return float(low), float(high)


def three_sigma(dof: int) -> float:
    """The NEES beyond which an estimate is off by more than its own 3 sigma (chi-square at 99.73 %)."""
    return float(chi2.ppf(0.9973, dof))


def nees_figures(values: np.ndarray, dof: int, probability: float = BAND_PROBABILITY) -> dict[str, float | int | list[float] | None]:
    """Mean NEES and the shares inside, above and below its band, over the finite values (None without any)."""
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    low, high = nees_band(dof, probability)
    if values.size == 0:
        return {"mean": None, "band": [low, high], "fraction_inside": None, "fraction_above": None, "fraction_below": None,
                "dof": dof, "epochs": 0}
    return {"mean": float(values.mean()), "band": [low, high], "fraction_inside": float(np.mean((values >= low) & (values <= high))),
            "fraction_above": float(np.mean(values > high)), "fraction_below": float(np.mean(values < low)), "dof": dof,
            "epochs": int(values.size)}
