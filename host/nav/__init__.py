"""The LOST navigation pipeline (NRL patent US 09/599,868) on top of the exact terrain correlator.

:func:`run_lost` drives the four stages of :mod:`lost.host.nav.stages` over a tow's records and a
bathymetric grid, with the lay-back model and dead reckoning as baselines on the same data.
"""

from .mapprep import PreparedMap
from .pipeline import NavParameters, NavResult, layback_distance, run_lost
from .stages import (
    CrossTrackTracker,
    TrackFrame,
    layback_position,
    patch_likelihood,
    point_likelihood,
    refine_minimum,
    slant_range_correct,
    state_update,
)

__all__ = [
    "CrossTrackTracker",
    "NavParameters",
    "NavResult",
    "PreparedMap",
    "TrackFrame",
    "layback_distance",
    "layback_position",
    "patch_likelihood",
    "point_likelihood",
    "refine_minimum",
    "run_lost",
    "slant_range_correct",
    "state_update",
]
