"""The survey planner: from the map alone, where terrain navigation will fix the position and how well.

:mod:`lost.host.plan.accuracy`: the Cramer-Rao bound of a correlation centred at every node; :mod:`lost.host.plan.ambiguity`:
the look-alikes of that correlation (the runner-up per distance ring); :mod:`lost.host.plan.route`: the predicted error
along a route, the lock acquired, lost and regained, with the dead reckoning's growth between informative stretches;
:mod:`lost.host.plan.output`: the files of ``lost plan``.
"""

from .accuracy import SonarModel, accuracy_grid, held_grid, held_sigma, information, map_sigma, survey_sigma
from .ambiguity import Lookalike, lookalike_grid
from .fill import Sweep, patch_fill
from .route import RouteModel, predict_along, predict_route, read_route, route_points

__all__ = ["Lookalike", "lookalike_grid", "SonarModel", "accuracy_grid", "information", "map_sigma", "survey_sigma", "held_sigma", "held_grid",
           "RouteModel", "predict_along", "predict_route", "read_route", "route_points", "Sweep", "patch_fill"]
