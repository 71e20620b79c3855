"""The result every correlator backend returns, and the one place that decides which placements count.

A placement is valid when the patch lies inside the map (the search area may reach past the map's
edges) and no valid node of the patch (its mask) falls on a hole of the map. A hole under a node the
mask leaves out decides nothing: V sums over the valid nodes alone (ARCHITECTURE.md), so the word a
hole is filled with never enters it, and a survey gridded from a few lines, mostly holes, still has
placements wherever the patch's soundings meet its depths. A hole under a valid node is refused, not
down-weighted: V there holds the fill word's difference as if it were a measured depth, and taking
that node out would need another mask per placement, which one correlation does not have. Only valid
placements can be the best fit or the runner-up; :func:`valid_placements` is the hole and edge policy,
and :class:`Correlation` carries its answer beside the surface, so no caller re-derives it with a
sentinel of its own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from lost.model import BestFit, Placement

__all__ = ["Area", "Correlation", "Outcome", "choose_fit", "valid_placements", "placed"]

#: ``(i0, j0, rows, cols)``: the placements ``i0 .. i0+rows-1`` by ``j0 .. j0+cols-1`` of a search.
Area = tuple[int, int, int, int]


@dataclass(frozen=True)
class Outcome:
    """What a backend computed for the in-map part of a search.

    Attributes
    ----------
    surface : int64 array
        V over the placements asked for.
    fit : BestFit or None
        The best fit the hardware computed over exactly these placements (relative to them), or None
        when the backend has none (software) or computed over other placements (padding, tiling).
    cycles : int or None
        Device clocks of the correlation(s), for a hardware backend.
    """

    surface: np.ndarray
    fit: BestFit | None = None
    cycles: int | None = None


@dataclass(frozen=True)
class Correlation:
    """One correlation: the surface, the placements that count, the best fit and the runner-up.

    Attributes
    ----------
    surface : (rows, cols) int64 array
        ``surface[r, c]`` is V at map placement ``(origin[0] + r, origin[1] + c)``; 0 where invalid
        because the placement leaves the map.
    valid : (rows, cols) bool array
        The placements inside the map where no valid node of the patch falls on a hole.
    best, runner_up : Placement or None
        In map placement coordinates; ``best`` is None when no placement is valid, ``runner_up`` when
        none is valid farther than ``exclusion_radius`` (Chebyshev) from the best.
    exclusion_radius : int
        The runner-up's exclusion radius, in nodes.
    origin : (int, int)
        The map placement of ``surface[0, 0]``.
    backend : str
        The backend's name.
    best_from : {"hardware", "host"}
        ``"hardware"`` when the device's own best fit and runner-up are reported (it correlated
        exactly these placements and every one is valid); ``"host"`` when they were found on the host
        among the valid placements.
    cycles : int or None
        Device clocks, for a hardware backend.
    """

    surface: np.ndarray
    valid: np.ndarray
    best: Placement | None
    runner_up: Placement | None
    exclusion_radius: int
    origin: tuple[int, int]
    backend: str
    best_from: str
    cycles: int | None = None

    @property
    def any_valid(self) -> bool:
        return self.best is not None

    @property
    def distinctness(self) -> float:
        """Runner-up V over best V (``inf`` without a runner-up, ``nan`` without a best fit)."""
        if self.best is None:
            return float("nan")
        if self.runner_up is None:
            return float("inf")
        return self.runner_up.value / max(self.best.value, 1)


def valid_placements(
    map_shape: tuple[int, int], patch_shape: tuple[int, int], area: Area, holes: np.ndarray | None = None,
    mask: np.ndarray | None = None, max_hole_share: float = 0.0,
) -> np.ndarray:
    """Bool ``(rows, cols)`` over ``area``: the patch lies inside the map and none of its valid nodes is on a hole.

    ``mask`` is the patch's valid mask (``patch_shape``; None: every node valid, the whole window counts).
    ``max_hole_share``: a placement keeps up to this share of its valid nodes (rounded down) on holes, their
    V terms then taken against the fill word (0, the default: none; the correlator's own rule).

    Raises
    ------
    ValueError
        ``holes`` not a boolean array of the map's shape, ``mask`` not one of the patch's, a share outside [0, 1).
    """
    (H, W), (h, w) = map_shape, patch_shape
    if not (isinstance(max_hole_share, (int, float)) and 0.0 <= max_hole_share < 1.0):
        raise ValueError(f"max_hole_share must be a number in [0, 1), got {max_hole_share!r}")
    i0, j0, rows, cols = area
    # The placements inside the map are one rectangle of the area: slices, not index arrays (a record asks this nine
    # times, once for each of its patches).
    top, bottom = max(i0, 0), min(i0 + rows, H - h + 1)
    left, right = max(j0, 0), min(j0 + cols, W - w + 1)
    valid = np.zeros((rows, cols), dtype=bool)
    inside = (slice(top - i0, bottom - i0), slice(left - j0, right - j0))
    any_inside = bottom > top and right > left
    if any_inside:
        valid[inside] = True
    if holes is None:
        return valid
    if not isinstance(holes, np.ndarray) or holes.dtype != np.bool_ or holes.shape != (H, W):
        raise ValueError(f"holes must be a boolean array of the map's shape {(H, W)}, got "
                         f"{getattr(holes, 'dtype', type(holes).__name__)} {getattr(holes, 'shape', '')}")
    if mask is not None:
        mask = np.asarray(mask)
        if mask.dtype != np.bool_ or mask.shape != (h, w):
            raise ValueError(f"mask must be a boolean array of the patch's shape {(h, w)}, got {mask.dtype} {mask.shape}")
    if not any_inside or not holes.any():
        return valid
    covered = holes[top : bottom - 1 + h, left : right - 1 + w]
    if not covered.any():
        return valid
    nodes = h * w if mask is None else int(mask.sum())
    valid[inside] = ~_touching(covered, mask, (h, w), int(max_hole_share * nodes))
    return valid


#: Output rows of hole counts made per FFT by :func:`_touching`: its memory is a block's, not a whole map's.
_HOLE_BLOCK_ROWS = 512
#: Up to this many holes under the placements' windows, :func:`_touching` counts them one by one rather than by FFT.
_FEW_HOLES = 48
#: Beyond them, a mask of up to this many valid nodes is counted node by node (one shifted window sum each) while that
#: adds at most ``_NODE_ADDS`` counts; an FFT beyond (it costs about as much at a 500 x 500 area).
_FEW_NODES = 64
_NODE_ADDS = 2_000_000


def _touching(covered: np.ndarray, mask: np.ndarray | None, patch_shape: tuple[int, int], allowed: int = 0) -> np.ndarray:
    """Bool over the placements of ``covered`` (a part of the hole mask): more than ``allowed`` valid patch nodes on holes."""
    h, w = patch_shape
    # Box sum of the hole mask over the windows, by a 2-D prefix sum of the nodes they cover alone: over the
    # whole map it cost 380 ms a call on a 4000 x 4000 map with holes, where the correlation takes 0.2 ms.
    count_type = np.int32 if covered.size < 2**31 else np.int64  # half the memory of a map-sized prefix sum
    prefix = np.zeros((covered.shape[0] + 1, covered.shape[1] + 1), dtype=count_type)
    prefix[1:, 1:] = np.cumsum(np.cumsum(covered, axis=0), axis=1)
    in_window = (prefix[h:, w:] - prefix[:-h, w:] - prefix[h:, :-w] + prefix[:-h, :-w]) > allowed
    if mask is None or mask.all():
        return in_window
    rows, cols = covered.shape[0] - h + 1, covered.shape[1] - w + 1
    touching = np.zeros((rows, cols), dtype=bool)
    if not mask.any() or not in_window.any():
        return touching  # holes under the valid nodes are at most the window's: none over the allowed, none under them
    hole_rows, hole_cols = np.nonzero(covered)
    node_rows, node_cols = np.nonzero(mask)
    if hole_rows.size > _FEW_HOLES and node_rows.size <= _FEW_NODES and node_rows.size * rows * cols <= _NODE_ADDS:
        # Many holes under a sparse mask (a swath's patch): each valid node adds the holes under it, shifted.
        counts = np.zeros((rows, cols), dtype=np.int32)
        for r, c in zip(node_rows.tolist(), node_cols.tolist()):
            counts += covered[r : r + rows, c : c + cols]
        return counts > allowed
    if hole_rows.size <= _FEW_HOLES:
        # A few holes: each adds the mask, turned about, to the placements whose window covers it (integers, exact).
        counts = np.zeros((rows, cols), dtype=np.int32)
        turned = mask[::-1, ::-1].astype(np.int32)
        for r, c in zip(hole_rows.tolist(), hole_cols.tolist()):
            top, left = max(r - h + 1, 0), max(c - w + 1, 0)
            bottom, right = min(r, rows - 1) + 1, min(c, cols - 1) + 1
            counts[top:bottom, left:right] += turned[top - r + h - 1 : bottom - r + h - 1, left - c + w - 1 : right - c + w - 1]
        return counts > allowed
    # The count of holes under the valid nodes is the hole mask correlated with the patch's mask: an FFT's
    # rounding error is some 1e-12 of a count of at most h * w, so "more than half a hole over" is exact.
    kernel = mask[::-1, ::-1].astype(np.float64)
    for top in range(0, rows, _HOLE_BLOCK_ROWS):
        bottom = min(top + _HOLE_BLOCK_ROWS, rows)
        block = covered[top : bottom + h - 1].astype(np.float64)
        touching[top:bottom] = signal.fftconvolve(block, kernel, mode="valid") > allowed + 0.5
    return touching


#: Rows of the surface examined at a time by :func:`choose_fit`: its working memory is a block, not a surface.
_FIT_BLOCK_ROWS = 256


def _first_min(surface: np.ndarray, valid: np.ndarray, rows: range, excluded: tuple[range, range] | None) -> tuple[int, int, int] | None:
    """(value, i, j) of the first smallest valid placement of ``rows`` in raster order, those in ``excluded`` left out."""
    ceiling = np.iinfo(np.int64).max
    best: tuple[int, int, int] | None = None
    for top in range(rows.start, rows.stop, _FIT_BLOCK_ROWS):
        bottom = min(top + _FIT_BLOCK_ROWS, rows.stop)
        block = np.where(valid[top:bottom], surface[top:bottom], ceiling)
        if excluded is not None:
            box_rows, box_cols = excluded
            a, b = max(box_rows.start, top) - top, min(box_rows.stop, bottom) - top
            if a < b:
                block[a:b, box_cols.start : box_cols.stop] = ceiling
        k = int(np.argmin(block))
        r, c = divmod(k, block.shape[1])
        value = int(block[r, c])
        if value == ceiling:
            continue  # nothing valid in this block (no valid V reaches the int64 ceiling)
        if best is None or value < best[0]:
            best = (value, top + r, c)
    return best


def choose_fit(surface: np.ndarray, valid: np.ndarray, exclusion_radius: int) -> BestFit | None:
    """The best fit and runner-up among the valid placements (relative coordinates); None if none is valid.

    The same answer as :func:`lost.model.best_fit` on the surface with the invalid placements set to
    the largest value (first smallest in raster order; the runner-up the first smallest beyond
    ``exclusion_radius``, Chebyshev), found block by block of rows: on an 8192 x 8192 map the whole-
    surface index arrays of the model's form cost 2.3 GB.
    """
    if not valid.any():
        return None
    rows, cols = surface.shape
    best = _first_min(surface, valid, range(rows), None)
    if best is None:
        return None
    value, i, j = best
    r = int(exclusion_radius)
    box = (range(max(i - r, 0), min(i + r + 1, rows)), range(max(j - r, 0), min(j + r + 1, cols)))
    second = _first_min(surface, valid, range(rows), box)
    runner_up = None if second is None else Placement(second[1], second[2], second[0])
    return BestFit(i, j, value, runner_up, r)


def placed(fit: BestFit | None, origin: tuple[int, int]) -> tuple[Placement | None, Placement | None]:
    """The best fit and runner-up of a sub-surface whose (0, 0) is the map's ``origin``, as map placements."""
    if fit is None:
        return None, None
    i0, j0 = origin
    ru = fit.runner_up
    return Placement(fit.i + i0, fit.j + j0, fit.value), None if ru is None else Placement(ru.i + i0, ru.j + j0, ru.value)
