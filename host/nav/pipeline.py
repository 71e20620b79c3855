"""Terrain navigation over a tow: :func:`navigate` runs a bank of estimators and both baselines; :func:`run_lost` the patent pipeline alone.

The parts live in their own modules: the constants in :mod:`lost.host.nav.parameters`, the estimators'
bank in :mod:`lost.host.nav.bank`, the record loop in :mod:`lost.host.nav.loop`, the results in
:mod:`lost.host.nav.results`.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING

from ..grid import Grid
from ..records import NavRecords
from .bank import ESTIMATORS, EstimatorBank
from .loop import RecordLoop, layback_distance
from .mapprep import PreparedMap
from .parameters import NavParameters
from .results import FilterTrack, NavResult

if TYPE_CHECKING:
    from ..usbl.sound import SoundSpeedProfile

__all__ = ["NavParameters", "NavResult", "FilterTrack", "ESTIMATORS", "navigate", "run_lost", "layback_distance"]


def run_lost(
    records: NavRecords,
    grid: Grid,
    params: NavParameters | None = None,
    *,
    prepared: PreparedMap | None = None,
    progress: Callable[[Iterable[int]], Iterable[int]] | None = None,
    profile: SoundSpeedProfile | None = None,
) -> NavResult:
    """The LOST patent pipeline alone (and both baselines) over a tow: ``navigate(..., estimators=("lost",))``."""
    return navigate(records, grid, params, estimators=("lost",), prepared=prepared, progress=progress, profile=profile)



def navigate(
    records: NavRecords,
    grid: Grid,
    params: NavParameters | None = None,
    *,
    estimators: Iterable[str] = ESTIMATORS,
    prepared: PreparedMap | None = None,
    progress: Callable[[Iterable[int]], Iterable[int]] | None = None,
    profile: SoundSpeedProfile | None = None,
) -> NavResult:
    """Run the named estimators and both baselines over a tow.

    Parameters
    ----------
    records : NavRecords
        The tow's sensor records.
    grid : Grid
        The bathymetry, in the records' frame.
    params : NavParameters
        Constants; the defaults are the patent's nominal values where it gives them.
    estimators : names from :data:`ESTIMATORS`
        Which to run, each on the same records.
    prepared : PreparedMap, optional
        The grid already quantized (to reuse across runs); built from ``grid`` otherwise.
    progress : callable, optional
        Wraps the record loop's iterable (e.g. ``rich.progress.track``).
    profile : SoundSpeedProfile, optional
        The sound speed (``lost.host.usbl``): a record's USBL travel time is ray-traced from the
        transducer (``reference_depth_m``) to the vehicle's depth into the slant range, which wins over
        the record's straight-line ``slant_range_m`` (counted ``slant_range_ray_traced`` and, where both
        were there, ``slant_range_ray_over_straight``). A travel time the ray cannot explain (too short
        for the depth, below the profile) falls back to ``slant_range_m`` (``usbl_ray_failed``);
        travel times without a profile are not used (``usbl_travel_time_without_profile``).

    Raises
    ------
    ValueError
        Patch matching on a tow without sonar patches, a sonar patch on other nodes than the map (a map
        coarser than the patches named as such), a prepared map of another grid, an unknown estimator.
    """
    params = params or NavParameters()
    prepared = prepared or PreparedMap.for_navigation(grid, params)
    if prepared.grid is not grid:
        raise ValueError("the prepared map was made from another grid than the one given")
    if params.matching == "patch" and not any(patch is not None for patch in records.sonar):
        raise ValueError("the tow has no sonar patch, so patch matching has nothing to match; use matching='point'")
    other = sorted({float(p.node_m) for p in records.sonar if p is not None and not math.isclose(p.node_m, grid.node_m, rel_tol=1e-9)})
    if other and other[0] < grid.node_m:
        raise ValueError(f"the map's {grid.node_m} m nodes are coarser than the sonar patches' {other[0]} m: the map cannot show "
                         "what the patches resolve; grid the patches on the map's nodes (block means of "
                         f"{grid.node_m / other[0]:g} x {grid.node_m / other[0]:g} of theirs) or use a finer map")
    if other:
        raise ValueError(f"the sonar patches have {', '.join(str(v) for v in other)} m nodes but the map {grid.node_m} m; "
                         "grid the patches on the map's nodes")
    counts: Counter = Counter()
    loop = RecordLoop(records, params, EstimatorBank(estimators, prepared, params, counts).estimators, counts, profile)
    iterator: Iterable[int] = range(len(records))
    if progress is not None:
        iterator = progress(iterator)
    for n in iterator:
        loop.step(n)
    return loop.result()

