"""Terrain navigation on top of the exact terrain correlator: the record loop over several estimators.

:func:`navigate` runs the LOST patent pipeline (NRL US 09/599,868; the four stages of
:mod:`lost.host.nav.stages`), the point-mass filter and the particle filter of Nygren's recursive
Bayesian estimation over a tow's records and a bathymetric grid, with the lay-back model and dead
reckoning as baselines on the same data; :func:`run_lost` runs the patent pipeline alone.
"""

from .estimator import Estimate, Estimator, Motion, Observation
from .mapprep import PreparedMap
from .pipeline import ESTIMATORS, FilterTrack, NavParameters, NavResult, layback_distance, navigate, run_lost
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
    "ESTIMATORS",
    "Estimate",
    "Estimator",
    "FilterTrack",
    "Motion",
    "Observation",
    "navigate",
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
