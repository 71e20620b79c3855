"""A correlator that holds one map for a whole run and correlates each record's patch once.

A navigation run asks for the same patch's surface several times per record: the patent pipeline over
its search area, each Bayesian filter over the placements its candidates span, each look-alike check
over a wider area around its estimate. :class:`ResidentCorrelator` holds the map (its words and holes,
validated once; for a device backend, its tile stays resident under a fixed key, so the map is never
hashed again), takes each record's patch once, and correlates it once over the union of the areas the
record's callers ask for. Every request is then a slice of that one surface, with the same integers,
valid placements and best fit as :func:`~lost.host.correlator.correlation` over the request alone.

The union is not known before the first request of a record comes, so the first request is widened to
the union of the previous record's requests, moved with it (the callers' areas follow the vehicle); a request that still
falls outside widens the surface once more (counted in ``stats["correlations"]``).

A record may have several patches (the same soundings gridded at sub-node offsets, :mod:`lost.host.nav.motion`), asked
for in turn by each caller: up to ``patches_held`` are held at once, the least recently used dropped first. Each comes
with its ``line`` (the record's own patch, one moved lattice), and a new patch is widened by its own line's previous
requests: a moved lattice's callers ask for less than the look-alike checks ask of the record's own patch.
"""

from __future__ import annotations

import itertools
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from lost import model

from . import _backend
from .backends import Backend
from .result import Area, Correlation, choose_fit, placed, valid_placements

__all__ = ["ResidentCorrelator"]

_KEYS = itertools.count()


def _union(a: Area, b: Area) -> Area:
    top, left = min(a[0], b[0]), min(a[1], b[1])
    bottom, right = max(a[0] + a[2], b[0] + b[2]), max(a[1] + a[3], b[1] + b[3])
    return top, left, bottom - top, right - left


def _inside(inner: Area, outer: Area) -> bool:
    return (outer[0] <= inner[0] and inner[0] + inner[2] <= outer[0] + outer[2]
            and outer[1] <= inner[1] and inner[1] + inner[3] <= outer[1] + outer[3])


@dataclass
class _Held:
    """One patch's state: its words and mask, and the surface over the area it has been asked for."""

    words: np.ndarray
    mask: np.ndarray
    area: Area | None = None
    surface: np.ndarray | None = None
    hole_free: np.ndarray | None = None  # over the held area: no valid patch node on a hole
    first: Area | None = None  # this patch's first request (in-map part)
    asked: Area | None = None  # the union of this patch's requests (in-map parts)
    line: object = None  # which of a record's patches it is: its line's next patch is widened by these requests


class ResidentCorrelator:
    """One map, held for a run; one correlation per patch over the union of the areas asked for.

    Parameters
    ----------
    words : (H, W) int16 array
        The map image (validated once here).
    holes : (H, W) bool array, optional
        Map nodes without a depth (placements where a valid node of the patch falls on one are not valid).
    backend : str or Backend
    mean_compensation : bool
    max_hole_share : float
        A placement may keep up to this share of the patch's valid nodes on holes (:func:`valid_placements`; 0: none).
    patches_held : int
        How many patches (and their surfaces) are held at once: a record's patches asked for in turn.

    Attributes
    ----------
    stats : dict
        ``patches`` (distinct patches loaded), ``correlations`` (backend calls), ``requests`` (areas served).
    """

    def __init__(self, words: np.ndarray, *, holes: np.ndarray | None = None, backend: str | Backend = "software",
                 mean_compensation: bool = True, max_hole_share: float = 0.0, patches_held: int = 1) -> None:
        self._backend = _backend(backend)
        probe = np.zeros((1, 1), np.int16)
        self._words, _, _ = model.check_inputs(words, probe, None, mean_compensation)
        self._holes = holes if holes is not None and holes.any() else None
        if self._holes is not None:
            valid_placements(self._words.shape, (1, 1), (0, 0, 1, 1), self._holes)  # refuses a mask of another shape
        self._mean_compensation = bool(mean_compensation)
        valid_placements((1, 1), (1, 1), (0, 0, 1, 1), None, None, max_hole_share)  # refuses a share outside [0, 1)
        self._max_hole_share = float(max_hole_share)
        if int(patches_held) < 1:
            raise ValueError(f"patches_held must be at least 1, got {patches_held!r}")
        self._capacity = int(patches_held)
        self._key = ("resident", next(_KEYS))  # the device's tile belongs to this map as long as this object lives
        self._held: OrderedDict[bytes, _Held] = OrderedDict()  # most recently used last
        self._previous: dict[object, tuple[Area, Area]] = {}  # per line, its last patch's first request and union
        self.stats = dict.fromkeys(("patches", "correlations", "requests"), 0)

    @property
    def shape(self) -> tuple[int, int]:
        return self._words.shape

    def correlation(self, patch: np.ndarray, mask: np.ndarray, area: Area, *, exclusion_radius: int | None = None,
                    line: object = None) -> Correlation:
        """The patch's correlation over ``area`` (which may reach past the map), as :func:`correlation` gives it.

        ``line``: which of a record's patches this is (None: the record's own), for the widening of its first request.

        Raises
        ------
        ValueError
            Bad patch words or mask, an area without placements.
        """
        surface, valid = self.surface(patch, mask, area, line=line)
        h, w = np.shape(patch)
        radius = max(h, w) // 2 if exclusion_radius is None else int(exclusion_radius)
        fit = choose_fit(surface, valid, radius)
        best, runner_up = placed(fit, area[:2])
        return Correlation(surface, valid, best, runner_up, radius, (int(area[0]), int(area[1])), self._backend.name, "host", None)

    def surface(self, patch: np.ndarray, mask: np.ndarray, area: Area, *, line: object = None) -> tuple[np.ndarray, np.ndarray]:
        """The patch's surface over ``area`` and its valid placements, as :meth:`correlation` gives them, without the
        best fit (a likelihood reads the whole surface)."""
        held = self._load(patch, mask, line)
        (H, W), (h, w) = self._words.shape, held.words.shape
        i0, j0, rows, cols = (int(v) for v in area)
        if rows < 1 or cols < 1:
            raise ValueError(f"area must have at least one placement, got rows={rows}, cols={cols}")
        self.stats["requests"] += 1
        on_map = (max(i0, 0), max(j0, 0), min(i0 + rows, H - h + 1) - max(i0, 0), min(j0 + cols, W - w + 1) - max(j0, 0))
        surface = np.zeros((rows, cols), dtype=np.int64)
        valid = np.zeros((rows, cols), dtype=bool)
        if on_map[2] > 0 and on_map[3] > 0:
            self._cover(held, on_map)
            a0, b0, n_rows, n_cols = on_map
            s0, t0 = a0 - held.area[0], b0 - held.area[1]
            surface[a0 - i0 : a0 - i0 + n_rows, b0 - j0 : b0 - j0 + n_cols] = held.surface[s0 : s0 + n_rows, t0 : t0 + n_cols]
            valid[a0 - i0 : a0 - i0 + n_rows, b0 - j0 : b0 - j0 + n_cols] = held.hole_free[s0 : s0 + n_rows, t0 : t0 + n_cols]
        return surface, valid

    def _load(self, patch: np.ndarray, mask: np.ndarray, line: object) -> _Held:
        """The held state of ``patch``: the same patch's again, or a new one validated (the oldest held dropped)."""
        key = patch.tobytes() + np.asarray(mask).tobytes() + str(patch.shape).encode()
        if key in self._held:
            self._held.move_to_end(key)
            return self._held[key]
        # The patch checked against itself (its words, its mask); against the map only by shape: the map was checked once.
        _, words, checked = model.check_inputs(patch, patch, mask, self._mean_compensation)
        if words.shape[0] > self._words.shape[0] or words.shape[1] > self._words.shape[1]:
            raise ValueError(f"patch of shape {words.shape} is larger than the terrain map of shape {self._words.shape}")
        while len(self._held) >= self._capacity:
            self._held.popitem(last=False)
        self._held[key] = held = _Held(words, checked, line=line)
        self.stats["patches"] += 1
        return held

    def _cover(self, held: _Held, area: Area) -> None:
        """Make ``held``'s surface cover the in-map ``area`` (one backend call when it does not yet)."""
        held.asked = area if held.asked is None else _union(held.asked, area)
        if held.area is None:
            held.first = area
            self._correlate(held, self._widened(area, held.line))
        elif not _inside(area, held.area):
            self._correlate(held, _union(held.area, area))
        self._previous[held.line] = (held.first, held.asked)

    def _widened(self, first: Area, line: object) -> Area:
        """A new patch's first request widened by what its line's previous patch was asked over, moved as its first
        request moved to this one."""
        if line not in self._previous:
            return first
        p_first, p_union = self._previous[line]
        di, dj = first[0] - p_first[0], first[1] - p_first[1]
        return _union(first, (p_union[0] + di, p_union[1] + dj, p_union[2], p_union[3]))

    def _correlate(self, held: _Held, wanted: Area) -> None:
        """One backend call: ``held``'s surface and hole rule over ``wanted``, clipped to the map's placements."""
        (H, W), (h, w) = self._words.shape, held.words.shape
        top, left = max(wanted[0], 0), max(wanted[1], 0)
        bottom, right = min(wanted[0] + wanted[2], H - h + 1), min(wanted[1] + wanted[3], W - w + 1)
        clipped = (top, left, bottom - top, right - left)
        outcome = self._backend.run(self._words, held.words, held.mask, self._mean_compensation, clipped, max(h, w) // 2,
                                    map_key=self._key)
        # The hole rule over the held area once per surface: each request is then a slice, as the surface is.
        held.area, held.surface = clipped, outcome.surface
        held.hole_free = valid_placements((H, W), (h, w), clipped, self._holes, held.mask, self._max_hole_share)
        self.stats["correlations"] += 1
