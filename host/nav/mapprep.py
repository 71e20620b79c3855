"""A :class:`~lost.host.grid.Grid` made ready for the correlator: 16-bit words and a hole policy.

Hole policy (NaN nodes in the map)
----------------------------------
The correlator needs a word at every node, so each hole is filled with the depth of its nearest
valid node before quantization. Where only nodes the patch's mask leaves out lie on holes the fill word
is not in V at all. A placement that puts more than ``max_hole_share`` of the patch's valid nodes on
holes is excluded from the estimate afterwards (:meth:`PreparedMap.placements_touching_holes`, the
correlator's :func:`~lost.host.correlator.valid_placements`); up to that share, those nodes count against
the fill, the nearest depth: an extrapolation that fits worse the further it reaches, so such a placement
is down-weighted by the misfit its filled nodes add rather than refused. The point-matching MLE simply
skips hole nodes.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from scipy import ndimage

from lost import model
from lost.model.correlator import DEPTH_MAX, DEPTH_MIN

from ..correlator import Area, Correlation, valid_placements
from ..correlator.resident import ResidentCorrelator
from ..grid import Grid
from .maperror import check_node_sigma
from .motion import MAX_PHASES

if TYPE_CHECKING:
    from .parameters import NavParameters

__all__ = ["PreparedMap", "LSB_CANDIDATES_M", "MAX_HOLE_SHARE"]

#: The share of a patch's valid nodes a placement may put on map holes (their terms then against the fill, the
#: nearest depth). Without it a narrow density beside a band of holes has a neighbour refused at every update and
#: dead-reckons as at the map's edge: on ``short`` (its survey map has holes of 300 m) 0 made the PMF's false fixes
#: and p90 (ten seeds: 14 false fixes and 0.521 node; 0.1, 0.2 and 0.35: none and 0.259). The fill is flat where it
#: reaches far, and a smooth shelf fits it: on ``shelf_canyon`` seed 0 the PF's RMS was 0.41 node at 0, 0.50 at 0.1,
#: 15.4 at 0.2 (the PMF's 0.65, 1.14, 1.89).
MAX_HOLE_SHARE = 0.1

#: How many patches a record may correlate: its own and its lattice-moved grids.
RECORD_PATCHES = MAX_PHASES**2

#: Depth steps tried in order, finest first, when the caller does not fix one.
LSB_CANDIDATES_M = (0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0)


class PreparedMap:
    """The int16 map image of a grid, with its scale, offset and holes.

    Parameters
    ----------
    grid : Grid
        The bathymetry; NaN nodes are holes.
    node_sigma_m : (H, W) array, optional
        The grid's per-node standard deviation, metres (an uncertainty layer, as gridding tools and BAG
        files carry); taken from the grid's ``sigma_m`` when it has one. NaN only on holes.
    max_hole_share : float
        A placement may put up to this share of the patch's valid nodes on holes, which then count against the
        fill (the nearest depth); default :data:`MAX_HOLE_SHARE`; 0: none, the correlator's own rule. The
        navigation passes ``NavParameters.max_hole_share``.
    lsb_m : float or None
        Metres per depth word. None picks the finest of :data:`LSB_CANDIDATES_M` that holds the map's
        depth range in half the word range, leaving the other half for sonar patches that deviate
        from the map (bias, outliers).

    Raises
    ------
    ValueError
        A grid with no valid node, a depth range that no candidate step holds, an uncertainty layer of
        another shape than the grid, negative, or NaN where the grid has a depth.
    """

    def __init__(self, *, grid: Grid, lsb_m: float | None = None, node_sigma_m: np.ndarray | None = None,
                 max_hole_share: float = MAX_HOLE_SHARE) -> None:
        depth = grid.depth_m
        holes = np.isnan(depth)
        if holes.all():
            raise ValueError("The map has no valid depth node: every node is a hole.")
        valid = depth[~holes]
        low, high = float(valid.min()), float(valid.max())
        offset_m = round((low + high) / 2.0, 2)
        if lsb_m is None:
            half_range = max(high - offset_m, offset_m - low)
            fitting = [lsb for lsb in LSB_CANDIDATES_M if half_range <= 0.5 * DEPTH_MAX * lsb]
            if not fitting:
                raise ValueError(f"The map's depth range {low:.1f}-{high:.1f} m is too wide for 16-bit words at any step up to {LSB_CANDIDATES_M[-1]} m.")
            lsb_m = fitting[0]
        if holes.any():
            # Nearest valid node's depth: a neutral value, since placements touching it are excluded.
            nearest = ndimage.distance_transform_edt(holes, return_distances=False, return_indices=True)
            depth = depth[tuple(nearest)]
        self._grid = grid
        self._holes = holes
        self._lsb_m = float(lsb_m)
        self._offset_m = float(offset_m)
        self._words = model.quantize(depth, self._lsb_m, offset_m=self._offset_m)
        # Checked once: most maps have no hole, and then no placement needs the hole policy.
        self._holes_or_none = holes if holes.any() else None
        valid_placements((1, 1), (1, 1), (0, 0, 1, 1), None, None, max_hole_share)  # refuses a share outside [0, 1)
        self._max_hole_share = float(max_hole_share)
        self._residents: dict[str, ResidentCorrelator] = {}
        # The grid's own uncertainty layer (a ``sigma_m`` of the grid, or given here): checked once.
        layer = node_sigma_m if node_sigma_m is not None else getattr(grid, "sigma_m", None)
        self._node_sigma = None if layer is None else check_node_sigma(layer, grid.depth_m)
        # The record's patches quantized, by identity (checked against their bytes): each caller's request reuses them.
        self._quantized: dict[int, tuple[np.ndarray, bytes, tuple[np.ndarray, np.ndarray, int]]] = {}

    @classmethod
    def for_navigation(cls, grid: Grid, params: NavParameters) -> PreparedMap:
        """The map as the navigation takes it: ``params``' depth step and hole share (batch and live alike)."""
        return cls(grid=grid, lsb_m=params.lsb_m, max_hole_share=params.max_hole_share)

    @property
    def max_hole_share(self) -> float:
        """The share of a patch's valid nodes a placement may put on holes."""
        return self._max_hole_share

    @property
    def grid(self) -> Grid:
        return self._grid

    @property
    def node_sigma_m(self) -> np.ndarray | None:
        """The map's per-node survey standard deviation, metres, when the grid carries one (0 on holes)."""
        return self._node_sigma

    @property
    def words(self) -> np.ndarray:
        """The int16 map image, holes filled (see the module's hole policy)."""
        return self._words

    @property
    def holes(self) -> np.ndarray:
        return self._holes

    @property
    def lsb_m(self) -> float:
        return self._lsb_m

    @property
    def offset_m(self) -> float:
        return self._offset_m

    def placements_touching_holes(self, patch_shape: tuple[int, int], area: Area | None = None,
                                  mask: np.ndarray | None = None) -> np.ndarray:
        """Bool array over ``area`` of the correlator's placements (default: all): True where a valid patch node is on a hole.

        ``mask`` is the patch's valid mask (None: every node of the window counts). The correlator's own
        policy (:func:`~lost.host.correlator.valid_placements`), edges aside.
        """
        h, w = (int(s) for s in patch_shape)
        rows, cols = self._holes.shape
        if not (1 <= h <= rows and 1 <= w <= cols):
            raise ValueError(f"a {h} x {w} patch does not fit in the {rows} x {cols} map")
        area = (0, 0, rows - h + 1, cols - w + 1) if area is None else area
        on_map = valid_placements((rows, cols), (h, w), area)
        return on_map & ~valid_placements((rows, cols), (h, w), area, self._holes_or_none, mask, self._max_hole_share)

    def correlation(self, words: np.ndarray, mask: np.ndarray, area: tuple[int, int, int, int], *, backend: str,
                    line: object = None) -> Correlation:
        """The patch's correlation over ``area`` = (i0, j0, rows, cols) of the map's placements, the map's holes applied.

        Served by the map's resident correlator for ``backend`` (:class:`~lost.host.correlator.resident.ResidentCorrelator`):
        a record's patch is correlated once over the union of the areas its callers ask for, and each
        gets its slice, identical to a correlation of its own area. ``line``: which of the record's patches this is
        (None: its own; a moved lattice's phase), as :meth:`ResidentCorrelator.correlation` takes it.
        """
        return self.resident(backend).correlation(words, mask, area, line=line)

    def surface(self, words: np.ndarray, mask: np.ndarray, area: tuple[int, int, int, int], *, backend: str,
                line: object = None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`correlation`'s surface and valid placements alone (no best fit), from the same resident correlator."""
        return self.resident(backend).surface(words, mask, area, line=line)

    def resident(self, backend: str) -> ResidentCorrelator:
        """The resident correlator of this map on ``backend`` (made on first use)."""
        if backend not in self._residents:
            # A record's patch and its lattice-moved grids (``likelihood_phases``) are held together.
            self._residents[backend] = ResidentCorrelator(self._words, holes=self._holes_or_none, backend=backend,
                                                          max_hole_share=self._max_hole_share, patches_held=RECORD_PATCHES)
        return self._residents[backend]

    def quantize_patch(self, depth_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
        """A sonar patch in the map's words, with its valid mask.

        NaN nodes (no beam) are invalid; so is any sounding outside the word range (an outlier far
        from every map depth), which is counted rather than clipped to a wrong word.

        Returns
        -------
        words : int16 array, patch : the quantized depths, 0 where invalid.
        mask : bool array, True where a beam is used.
        out_of_range : int, how many finite soundings were dropped for not fitting a word.
        """
        held = self._quantized.get(id(depth_m))
        if held is not None and held[0] is depth_m and held[1] == depth_m.tobytes():
            return held[2]  # the same record's patch again: quantized once
        depth = np.asarray(depth_m, dtype=np.float64)
        finite = np.isfinite(depth)
        low_m = self._offset_m + DEPTH_MIN * self._lsb_m
        high_m = self._offset_m + DEPTH_MAX * self._lsb_m
        fits = finite & (depth >= low_m) & (depth <= high_m)
        words = np.zeros(depth.shape, dtype=np.int16)
        words[fits] = model.quantize(depth[fits], self._lsb_m, offset_m=self._offset_m)
        quantized = words, fits, int((finite & ~fits).sum())
        if isinstance(depth_m, np.ndarray):
            words.flags.writeable = fits.flags.writeable = False  # shared by the record's callers
            if len(self._quantized) >= RECORD_PATCHES:
                self._quantized.pop(next(iter(self._quantized)))
            self._quantized[id(depth_m)] = (depth_m, depth_m.tobytes(), quantized)
        return quantized
