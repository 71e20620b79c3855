"""Depth positive down from a file's values: the sign from the caller, metadata or the data, nodata and plausibility."""

from __future__ import annotations

import logging

import numpy as np

from .filecheck import check_plausible

log = logging.getLogger(__name__)

_DOWN_WORDS = ("depth",)
_UP_WORDS = ("elevation", "height", "altitude", "topo")

# --------------------------------------------------------------------------------------------
# shared steps


#: A share of values on the other side of zero from the median above which the data's sign is no guide.
MIXED_SIGN_SHARE = 0.1


def _to_depth(values: np.ndarray, positive: str | None, name: str, variable: str, nodata: float | None = None) -> np.ndarray:
    """The file's values as depth (positive down): holes for ``nodata``, implausible values refused, the sign applied."""
    if nodata is not None:
        values = np.where(values == nodata, np.nan, values)
    check_plausible(values, name, variable)
    if positive is None:
        positive = _sign_from_data(values, name, variable)
    if positive == "up":
        log.info("%s: %s is elevation (positive up); negated to depth (positive down)", name, variable)
        return -values
    return values


def _sign_from_data(values: np.ndarray, name: str, variable: str) -> str:
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        raise ValueError(f"{name}: {variable} holds no finite value")
    median = float(np.median(finite))
    below, above = float(np.mean(finite < 0)), float(np.mean(finite > 0))
    if median >= 0 and below >= MIXED_SIGN_SHARE:
        # Mostly land at +60 m with sea at -40 m, or a depth grid with much ground above its datum: the median cannot tell.
        raise ValueError(
            f"{name}: {variable} has no sign convention in its metadata and holds both signs in earnest ({above:.0%} above zero, "
            f"{below:.0%} below): elevation over mostly land or depth with dry ground, the data cannot tell; "
            "pass positive='up' (elevation, as GEBCO) or 'down' (depth), --positive on the command line"
        )
    positive = "up" if median < 0 else "down"
    # A guess from the data, so it is said at WARNING (Python prints it even when logging is not set up,
    # and the command line puts it in the run's report).
    log.warning(
        "%s: %s has no sign convention in its metadata; its median is %s, so it is read as %s "
        "(pass positive='up' or 'down', --positive on the command line, to say otherwise)",
        name, variable, f"{median:g}", "elevation (negated to depth)" if positive == "up" else "depth",
    )
    return positive


def _ascending(values: np.ndarray, xs: np.ndarray, ys: np.ndarray, name: str):
    """Flip so both coordinate vectors ascend (north-up files become row 0 south)."""
    for _axis, coords, label in ((1, xs, "x"), (0, ys, "y")):
        if coords.size > 1:
            steps = np.diff(coords)
            if not (np.all(steps > 0) or np.all(steps < 0)):
                raise ValueError(f"{name}: the {label} coordinates are not strictly monotonic")
    if xs.size > 1 and xs[1] < xs[0]:
        values, xs = values[:, ::-1], xs[::-1]
    if ys.size > 1 and ys[1] < ys[0]:
        values, ys = values[::-1, :], ys[::-1]
    return np.ascontiguousarray(values), xs, ys


def _sign_from_metadata(attrs: dict, variable: str) -> str | None:
    cf_positive = str(attrs.get("positive", "")).lower()
    if cf_positive in ("down", "up"):
        return cf_positive
    words = " ".join(str(s).lower() for s in (variable, attrs.get("standard_name", ""), attrs.get("long_name", "")))
    if any(w in words for w in _DOWN_WORDS):
        return "down"
    if any(w in words for w in _UP_WORDS):
        return "up"
    return None


