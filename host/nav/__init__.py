"""Terrain navigation on top of the exact terrain correlator: the record loop over several estimators.

:func:`navigate` runs the LOST patent pipeline (NRL US 09/599,868; the four stages of
:mod:`lost.host.nav.stages`), the point-mass filter and the particle filter of Nygren's recursive
Bayesian estimation over a tow's records and a bathymetric grid, with the lay-back model and dead
reckoning as baselines on the same data; :func:`run_lost` runs the patent pipeline alone.
"""

from .bank import ESTIMATORS, EstimatorBank, register_estimator
from .estimator import Estimate, Estimator, Motion, Observation
from .loop import layback_distance
from .mapprep import PreparedMap
from .parameters import NavParameters, navigation_parameters
from .pipeline import navigate, run_lost
from .results import FilterTrack, NavResult
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
    "EstimatorBank",
    "register_estimator",
    "navigation_parameters",
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
