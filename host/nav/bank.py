"""The estimators of a run, registered by name, built on one prepared map: :class:`EstimatorBank`.

As MB-System's TRN keeps its filters behind one interface in a bank, each estimator here is made by a
factory registered under its name (:func:`register_estimator`); :data:`ESTIMATORS` are the built-in
ones: the LOST patent pipeline, the point-mass filter and the particle filter. The Bayesian filters of
a bank share one terrain likelihood, and through it one correlation per record.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass

from .estimator import Estimator
from .likelihood import TerrainLikelihood, map_error_estimate
from .maperror import node_variance, uniform_equivalent
from .mapprep import PreparedMap
from .parameters import NavParameters
from .patent import PatentEstimator
from .pf import ParticleFilter
from .pmf import PointMassFilter

__all__ = ["ESTIMATORS", "BankContext", "EstimatorBank", "register_estimator", "registered_estimators"]


@dataclass(frozen=True)
class BankContext:
    """What a factory builds an estimator from: the map, the settings, the run's shared counts and likelihood."""

    prepared: PreparedMap
    params: NavParameters
    counts: Counter
    likelihood: Callable[[], TerrainLikelihood]


EstimatorFactory = Callable[[BankContext], Estimator]

_FACTORIES: dict[str, EstimatorFactory] = {}


def register_estimator(name: str, factory: EstimatorFactory) -> None:
    """Make ``factory`` the estimator called ``name`` (``lost run --estimator``); a name is registered once."""
    if not name or not name.isidentifier():
        raise ValueError(f"an estimator's name must be a non-empty identifier, got {name!r}")
    if name in _FACTORIES:
        raise ValueError(f"an estimator called {name!r} is already registered")
    _FACTORIES[name] = factory


def registered_estimators() -> tuple[str, ...]:
    """Every registered estimator's name, in registration order."""
    return tuple(_FACTORIES)


register_estimator("lost", lambda c: PatentEstimator(c.prepared, c.params, c.counts))
register_estimator("pmf", lambda c: PointMassFilter(c.likelihood(), c.params, grid=c.prepared.grid))
register_estimator("pf", lambda c: ParticleFilter(c.likelihood(), c.params, grid=c.prepared.grid, seed=c.params.seed))

#: The built-in estimators of ``navigate`` (``lost run --estimator``).
ESTIMATORS = ("lost", "pmf", "pf")


class EstimatorBank:
    """The named estimators of one run, on one prepared map, in the order named.

    Parameters
    ----------
    names : names from :func:`registered_estimators`
    prepared : PreparedMap
    params : NavParameters
    counts : Counter
        The run's counts, shared with the patent pipeline.

    Raises
    ------
    ValueError
        No name, or a name not registered.
    """

    def __init__(self, names: Iterable[str], prepared: PreparedMap, params: NavParameters, counts: Counter) -> None:
        names = list(names)
        known = registered_estimators()
        unknown = sorted(set(names) - set(known))
        if unknown or not names:
            raise ValueError(f"estimators must be some of {known}, got {names!r}")
        if len(set(names)) != len(names):
            raise ValueError(f"each estimator is named once, got {names!r}")
        self._prepared, self._params = prepared, params
        self._likelihood: TerrainLikelihood | None = None
        context = BankContext(prepared, params, counts, self.likelihood)
        self.estimators: list[Estimator] = [_FACTORIES[name](context) for name in names]

    def likelihood(self) -> TerrainLikelihood:
        """The terrain likelihood every Bayesian filter of the bank shares (made on first use).

        With ``map_error_m`` given, one residual sigma ``hypot(depth_noise_m, map_error_m)``; else, with
        ``map_error_model = "per_node"``, each placement's own (:mod:`lost.host.nav.maperror`: the grid's
        uncertainty layer or ``survey_sigma_m``, plus slope and relief), the nominal sigma being their median;
        with ``"uniform"``, ``likelihood.map_error_estimate``.
        """
        if self._likelihood is None:
            params, prepared = self._params, self._prepared
            node_var = None
            if params.map_error_m is not None:
                map_error = params.map_error_m
            elif params.map_error_model == "per_node":
                survey = prepared.node_sigma_m if prepared.node_sigma_m is not None else params.survey_sigma_m
                node_var = node_variance(prepared.grid.depth_m, prepared.grid.node_m, survey)
                map_error = uniform_equivalent(node_var)
            else:
                map_error = map_error_estimate(prepared.grid.depth_m)
            sigma = math.hypot(params.depth_noise_m, map_error)
            self._likelihood = TerrainLikelihood(prepared, sigma_m=sigma, depth_sigma_m=sigma, form=params.likelihood, backend=params.backend,
                                                 node_var_m2=node_var, depth_noise_m=params.depth_noise_m,
                                                 phases=params.likelihood_phases)
        return self._likelihood

    def __iter__(self):
        return iter(self.estimators)

    def __len__(self) -> int:
        return len(self.estimators)
