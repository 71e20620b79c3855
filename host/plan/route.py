"""The predicted error along a route: the lock on the true position, its accuracy, and the look-alikes that take it.

The vehicle follows the waypoints at a constant speed and correlates a patch every ``interval_s``. The prediction is a
mixture of two states, as a Monte Carlo of the filters shows them:

- Holding the lock: a Gaussian error (per axis variance ``P``). Between updates it grows as the filters' density does:
  the velocity noise as a random walk (``velocity_noise_mps``), a free INS's bias terms (Nygren eq. 6.2,
  ``lost.host.nav.trust.ins_position_sigma``) from the last update, and what is not yet known of the velocity bias (its
  sigma times the time since the fix), the bias learned as the filters learn it (their Kalman filter,
  ``lost.host.nav.velocity_bias``, on every fix once ``bias_learning_updates`` have come in a row: slowly early in a tow,
  well after a long informative stretch). An update whose bound (:mod:`lost.host.plan.accuracy`)
  is within ``usable_sigma_m`` fuses as a Gaussian measurement of the share of its patch that is new (the filters
  temper each patch so: ``1/P += 2 share / bound^2``, the bound being horizontal); a larger bound is no fix and the
  error keeps growing. The filters keep
  their density at least ``floor_m`` wide, so no update takes ``P`` below it. ``P`` is the density's width, which sets
  the lock's odds against its look-alikes; the error of the position held is another thing (``held``): the error of
  one patch's fit with the map's error against the sonar's patch alone (:func:`lost.host.plan.accuracy.held_sigma`: no
  slope allowance, no density floor) weighed as the filters weigh the patch's nodes (their allowance included:
  :func:`lost.host.plan.accuracy.held_grid`), not averaged along the track, since the map's errors and the relief a node
  cannot show are the same on every pass over a place and the patches of one stretch share them. Each fix moves the
  estimate the update's Kalman gain of the way from the error it held to that patch's (summed as amplitudes: the same
  errors), so after a gap the error comes back over some 1/gain updates, and along the track it follows the patches'
  errors smoothed over as many (on ``coarse_map``, 1/gain is about 200 updates). Where there is no fix
  it grows from the last one by the velocity sensor's own noise and the part of its bias the filters have not learned
  where those are known (``sensor_velocity_noise_mps``, ``sensor_velocity_bias_mps``: :meth:`_Lock.held_growth_ms`),
  else as the density does; on one axis of the two where a slant range holds the other (``slant_range``).
- Not holding it (probability ``unlocked``): still searching (the error shown is the start's, ``initial_error_m``, or
  the initial search's ``2 initial_sigma_m^2`` where the start is not given), or holding a wrong place (a look-alike's
  distance); both drift with the dead reckoning.

The map is read where the patch lies: ``patch_lag_m`` behind the vehicle along the track for a real-time patch, which
holds only the pings received so far (swept by its swath where ``sweep`` says how, :mod:`lost.host.plan.fill`; else
taken to fill over its first patch length): its bound is wider and its separations from the look-alikes smaller by the
share of it sounded, and under ``min_valid_fraction`` of it (the navigation's) there is no terrain update.

The look-alikes (:mod:`lost.host.plan.ambiguity`: per distance ring, the runner-up's separation ``snr``, distance and
the ring's rivals, one per basin of the misfit) move the probability between the states:

- The search ends on accumulated evidence: per ring, the new share of each patch (the track run since the last terrain
  update over the patch length, as the filters temper it: the first patch wholly) times the ring's smallest separation
  adds up, and each of the ring's look-alikes as good as its best is still ahead of the truth with
  ``Phi(-sqrt(evidence) / 2)`` (:func:`_still_searching`). Rough ground ends it within a patch length, repeated
  terrain never; a hole adds nothing, and a search over a hole narrows (a patch length of such updates) into a wrong
  lock: the filter updates on the patch's valid nodes, where the truth's placement is neutral and the others are not.
  The wrong place is where the search's density reaches beyond the nearest look-alike as good as the truth (a ring's
  best with rivals of at least one half, at ``r0``): as a Bayesian filter with a flat likelihood over look-alikes
  spread evenly beyond ``r0`` would hold it, at a mean square distance ``r0^2 + 2 initial_sigma_m^2``
  (:func:`_wrong_place_ms`); without such a look-alike, anywhere in the search's density.
- A lock slips onto a ring's best look-alike with the probability a new patch prefers it against the locked density's
  own odds, ``Phi(-(snr / 2c + d^2 / 2P) / sqrt(snr / c))`` (``c``: the look-alikes' ``evidence_scale``), summed over
  the rings beyond three sigma, per new patch.
- A wrong lock is left where the terrain fixes the position and no look-alike within twice its error competes: per new
  patch, one minus the rivals of those rings, with ``acquisitions_per_patch`` chances in the length of a patch. A wrong
  lock therefore persists over smooth or look-alike ground and is left on informative terrain.

The predicted error is ``sqrt((1 - unlocked) H^2 + unlocked E^2)``, ``H`` the held error (``2P`` without ``held``).

Without look-alikes the filter is taken to hold the lock from the start (the bound and the growth only).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.special import ndtr

from ..grid import Grid
from .ambiguity import Lookalike
from .fill import Sweep, patch_fill

__all__ = ["RouteModel", "read_route", "route_points", "predict_route", "predict_along", "false_lock_probability"]


@dataclass(frozen=True, kw_only=True)
class RouteModel:
    """The motion, dead reckoning and filter assumptions of a route prediction (module docstring).

    ``patch_length_m`` is a patch's extent along the track (the share of it new at each update is the filters'
    tempering); ``patch_lag_m`` how far behind the vehicle along the track its patch is centred (a real-time patch of
    the pings received so far: :attr:`lost.host.plan.accuracy.SonarModel.lag_m`), where the map's bound and look-alikes
    are taken; ``acquisitions_per_patch`` is fitted to the Monte Carlo of the point-mass filter on the four shipped floors
    with the look-alikes' ``evidence_scale`` (``benchmarks/plan_fit.py``, which also scores each floor held out of the
    fit; ``docs/campaign.md``).

    ``sensor_velocity_noise_mps`` and ``sensor_velocity_bias_mps`` (east, north) are the velocity sensor's own errors (a
    scenario's, a datasheet's), where they are known: the error held then grows between fixes by those and the part of
    the bias the filters have not learned, while the density (the look-alikes' odds) grows by the filters' assumptions.
    Unknown (None), the filters' assumptions are taken as the truth. ``initial_error_m`` is the start's expected horizontal
    error (a lay-back model's, a fix's), which the estimate shows while the filters search (held within dead reckoning's
    reach); None: the filters' prior (``initial_sigma_m`` each axis). ``min_valid_fraction`` is the share of a patch's
    nodes the navigation needs to correlate it (``NavParameters.min_valid_fraction``); ``sweep`` a real-time swath's
    geometry (:class:`lost.host.plan.fill.Sweep`; ``lost.host.cli.plan.scenario_motion`` takes it from a scenario).
    ``slant_range``: the filters take the ship's slant range to the vehicle, which holds the error along it (a metre or
    two), so that the error held grows between fixes on the axis across it alone.
    """

    speed_mps: float = 1.5
    interval_s: float = 1.0
    initial_sigma_m: float = 50.0
    velocity_noise_mps: float = 0.05
    gyro_bias_rps: float = float(np.radians(0.01) / 3600.0)
    accel_bias_mps2: float = 10e-6 * 9.81
    usable_sigma_m: float = 10.0
    floor_m: float = 0.0
    patch_length_m: float = 100.0
    acquisitions_per_patch: float = 10.0
    patch_lag_m: float = 0.0
    velocity_bias_sigma_mps: float = 0.0
    velocity_bias_walk_mps: float = 0.0
    bias_learning_updates: int = 5
    min_valid_fraction: float = 0.0
    sweep: Sweep | None = None
    slant_range: bool = False
    sensor_velocity_noise_mps: float | None = None
    sensor_velocity_bias_mps: tuple[float, float] | None = None
    initial_error_m: float | None = None

    @classmethod
    def from_navigation(cls, params: Any, node_m: float, patch_nodes: float = 10.0, **motion: float) -> RouteModel:
        """The model the navigation's parameters (``NavParameters``) imply on a map of ``node_m`` with a patch of
        ``patch_nodes`` a side: its initial search, dead reckoning's noise and biases, usable threshold and density's floor;
        ``motion`` sets speed_mps and interval_s (and may set initial_sigma_m, patch_lag_m, initial_error_m and the velocity sensor's errors)."""
        return cls(**{"initial_sigma_m": params.initial_sigma_m, **motion}, velocity_noise_mps=params.velocity_noise_mps,
                   gyro_bias_rps=params.gyro_bias_rps, accel_bias_mps2=params.accel_bias_mps2, usable_sigma_m=params.usable_sigma_nodes * node_m,
                   floor_m=float(np.hypot(params.position_floor_nodes * node_m, params.position_floor_tracking_m)), patch_length_m=patch_nodes * node_m,
                   **({"velocity_bias_sigma_mps": params.velocity_bias_sigma_mps, "velocity_bias_walk_mps": params.velocity_bias_walk_mps,
                       "bias_learning_updates": params.bias_learning_updates} if params.estimate_velocity_bias else {}),
                   min_valid_fraction=params.min_valid_fraction)

    def __post_init__(self) -> None:
        for name in ("speed_mps", "interval_s", "initial_sigma_m", "usable_sigma_m", "patch_length_m", "acquisitions_per_patch"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        for name in ("patch_lag_m", "velocity_bias_sigma_mps", "velocity_bias_walk_mps", "sensor_velocity_noise_mps", "initial_error_m"):
            value = getattr(self, name)
            if value is not None and not (np.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a non-negative number, got {value!r}")
        if self.sensor_velocity_bias_mps is not None:
            bias = np.asarray(self.sensor_velocity_bias_mps, dtype=np.float64)
            if bias.shape != (2,) or not np.isfinite(bias).all():
                raise ValueError(f"sensor_velocity_bias_mps must be two finite numbers (east, north), got {self.sensor_velocity_bias_mps!r}")
        if not (np.isfinite(self.min_valid_fraction) and 0.0 <= self.min_valid_fraction <= 1.0):
            raise ValueError(f"min_valid_fraction must lie in [0, 1], got {self.min_valid_fraction!r}")
        if isinstance(self.bias_learning_updates, bool) or not (isinstance(self.bias_learning_updates, (int, np.integer)) and self.bias_learning_updates >= 1):
            raise ValueError(f"bias_learning_updates must be a whole number of at least 1, got {self.bias_learning_updates!r}")


def read_route(path: Path) -> np.ndarray:
    """Waypoints from a CSV with ``east_m`` and ``north_m`` columns (a header row), in the map's projected CRS.

    Raises
    ------
    ValueError
        A missing column, a non-number, fewer than two waypoints: the file and line named.
    """
    with open(path, newline="", encoding="utf-8") as handle:
        reader = csv.DictReader(handle)
        columns = {name.strip().lower(): name for name in reader.fieldnames or ()}
        if not {"east_m", "north_m"} <= set(columns):
            raise ValueError(f"{path}: a route needs the columns east_m and north_m, it has {sorted(columns) or 'none'}")
        points = []
        for line, row in enumerate(reader, start=2):
            try:
                points.append((float(row[columns["east_m"]]), float(row[columns["north_m"]])))
            except (TypeError, ValueError):
                raise ValueError(f"{path}, line {line}: east_m and north_m must be numbers, got {row}") from None
    route = np.asarray(points, dtype=np.float64)
    if len(route) < 2 or not np.isfinite(route).all():
        raise ValueError(f"{path}: a route needs at least two finite waypoints, got {len(route)}")
    return route


def route_points(waypoints: np.ndarray, model: RouteModel) -> tuple[np.ndarray, np.ndarray]:
    """Times and positions of the updates along the waypoints at ``model.speed_mps``, every ``model.interval_s``."""
    legs = np.diff(waypoints, axis=0)
    distance = np.concatenate(([0.0], np.cumsum(np.hypot(*legs.T))))
    t = np.arange(0.0, distance[-1] / model.speed_mps + 1e-9, model.interval_s)
    along = t * model.speed_mps
    return t, np.column_stack([np.interp(along, distance, waypoints[:, 0]), np.interp(along, distance, waypoints[:, 1])])


def predict_route(accuracy: Grid, waypoints: np.ndarray, model: RouteModel, lookalike: Lookalike | None = None,
                  held: Grid | None = None) -> dict[str, np.ndarray]:
    """The prediction at every update along the waypoints, with the map's bound (and look-alikes, and the held error's bound) there."""
    t, xy = route_points(waypoints, model)
    return predict_along(accuracy, t, xy, model, lookalike, held)


def _behind(xy: np.ndarray, lag_m: float) -> np.ndarray:
    """The positions ``lag_m`` back along the track from each of ``xy`` (the track's first position where it has not
    gone that far: a real-time patch then lies about its first pings)."""
    if lag_m <= 0 or len(xy) < 2:
        return xy
    along = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    back = np.maximum(along - lag_m, 0.0)
    return np.column_stack([np.interp(back, along, xy[:, 0]), np.interp(back, along, xy[:, 1])])


def _sample(accuracy: Grid, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nearest node of each position, and which positions are on the map."""
    row, col = accuracy.row_col(xy[:, 0], xy[:, 1])
    finite = np.isfinite(row) & np.isfinite(col)
    r, c = np.rint(np.where(finite, row, -1)).astype(int), np.rint(np.where(finite, col, -1)).astype(int)
    on_map = finite & (r >= 0) & (r < accuracy.shape[0]) & (c >= 0) & (c < accuracy.shape[1])
    return r, c, on_map


class _Lock:
    """The state holding the lock: the density's variance per axis (``p``), grown between fixes and narrowed by them, with
    the velocity bias as the filters learn it (their own Kalman filter on the density's corrections: its variance alone,
    which does not depend on the corrections' values)."""

    def __init__(self, model: RouteModel, t0: float, share: float) -> None:
        from ..nav.velocity_bias import VelocityBiasFilter

        self._model, self._share = model, share
        self.p_fix, self.last_fix, self.fixed = model.initial_sigma_m**2 / 2, t0, False
        self._bias = VelocityBiasFilter(model.velocity_bias_sigma_mps, model.velocity_bias_walk_mps) if model.velocity_bias_sigma_mps > 0 else None
        self._fixes_in_row, self._last_learned = 0, t0
        self.gain = 0.0  # the last update's Kalman gain: the share of the way its estimate moved to the fix
        bias = model.sensor_velocity_bias_mps
        self._true_bias_ms = None if bias is None else np.square(np.asarray(bias, dtype=np.float64))  # per axis, (m/s)^2

    def advance(self, time_s: float, step: float, first: bool, usable: bool, bound: float) -> float:
        """The density's variance per axis at ``time_s``: grown since the last fix, and a fix there if ``usable``."""
        from ..nav.trust import ins_position_sigma

        model, bias = self._model, self._bias
        since = time_s - self.last_fix
        ins = float(ins_position_sigma(since, gyro_bias_rps=model.gyro_bias_rps, accel_bias_mps2=model.accel_bias_mps2))
        if bias is not None and not first:
            bias.walk(step)
        bias_var = float(bias.variance_mps2.max()) if bias is not None else 0.0
        # without a fix the density widens by the velocity noise (a random walk), the free INS's biases and what is
        # not known of the velocity bias (its sigma times the time since the fix)
        p = self.p_fix + model.velocity_noise_mps**2 * since * step + ins**2 + bias_var * since**2
        if not usable:
            self.fixed, self._fixes_in_row, self.gain = False, 0, 0.0
            return p
        new = self._share if self.fixed else 1.0 if first else min(1.0, model.speed_mps * since / model.patch_length_m)
        posterior = 1.0 / (1.0 / p + 2.0 * new / bound**2)
        self.gain = 1.0 - posterior / p  # the mean moves by the gain; the floor widens the density only after
        p = max(posterior, model.floor_m**2 / 2)  # horizontal: half an axis
        self.p_fix, self.last_fix, self.fixed = p, time_s, True
        self._fixes_in_row += 1
        if bias is not None:
            if self._fixes_in_row >= model.bias_learning_updates:  # learned only while the density has been narrow a while
                bias.update(np.zeros(2), time_s - self._last_learned, np.full(2, posterior), new)
            elif bias.following:
                bias.restart()
            self._last_learned = time_s
        return p

    def held_growth_ms(self, since_s: float, step: float) -> float | None:
        """How far the error held has grown (horizontal mean square, m^2) ``since_s`` after its fix, by the velocity
        sensor's own errors (None where the model does not know them: the density's growth stands for it).

        Per axis, a Kalman filter that started at zero with the prior ``P0`` and holds the variance ``P`` has shrunk a true
        bias ``b`` by ``k = P / P0``: what is left has the mean square ``k^2 b^2 + P (1 - k)`` (``P`` where ``b^2`` is
        ``P0``: the filter consistent). A filter without the bias state leaves all of it."""
        from ..nav.trust import ins_position_sigma

        model = self._model
        if model.sensor_velocity_noise_mps is None and model.sensor_velocity_bias_mps is None:
            return None
        noise = model.velocity_noise_mps if model.sensor_velocity_noise_mps is None else model.sensor_velocity_noise_mps
        ins = float(ins_position_sigma(since_s, gyro_bias_rps=model.gyro_bias_rps, accel_bias_mps2=model.accel_bias_mps2))
        true_bias_ms = self._true_bias_ms
        if self._bias is None:
            left = np.zeros(2) if true_bias_ms is None else true_bias_ms
        else:
            variance = self._bias.variance_mps2
            if true_bias_ms is None:
                left = variance
            else:
                shrunk = np.minimum(variance / model.velocity_bias_sigma_mps**2, 1.0)
                left = shrunk**2 * true_bias_ms + variance * (1.0 - shrunk)
        return 2.0 * (noise**2 * since_s * step + ins**2) + float(np.sum(left)) * since_s**2


class _Unlocked:
    """The states not holding the lock: still searching, or slipped onto a wrong place; their probabilities and mean
    square errors, moved by the look-alikes (module docstring)."""

    def __init__(self, model: RouteModel, lookalike: Lookalike, share: float) -> None:
        self._model, self._lookalike, self._share = model, lookalike, share
        self.searching, self.search_ms = 1.0, 2.0 * model.initial_sigma_m**2
        # what a user sees while the search goes on: the start held (dead reckoning's), not the search's density
        self.shown_ms = self.search_ms if model.initial_error_m is None else model.initial_error_m**2
        self.slipped, self.slip_ms = 0.0, 0.0
        self._evidence = np.zeros(len(lookalike.ring_edges_m))  # per ring, against its best look-alike
        self._nearest_m = 0.0  # the nearest look-alike as good as the truth, last seen (none: 0)
        self._untempered_m = np.inf  # track run since the last terrain update (the first patch is wholly new)

    def advance(self, step: float, p: float, usable: bool, on_map: bool, snr: np.ndarray, distance_m: np.ndarray,
                rivals: np.ndarray) -> tuple[float, float]:
        """One update with the held density's variance ``p`` and the rings' look-alikes there: the probability of not
        holding the truth and the mean square error then."""
        model, lookalike, share = self._model, self._lookalike, self._share
        drift = 2.0 * (model.velocity_noise_mps * step) ** 2  # a wrong position drifts as dead reckoning does
        self.search_ms, self.slip_ms, self.shown_ms = self.search_ms + drift, self.slip_ms + drift, self.shown_ms + drift
        if np.isfinite(rivals).any():
            self._nearest_m = _nearest_lookalike(distance_m, rivals)
        if on_map and np.isnan(snr).all() and self.searching > 0.0:
            # a search over a hole of the map: the filter still updates on the patch's valid nodes, where the truth's
            # placement is neutral and the others are not, and narrows onto a wrong place (a false lock, not a search)
            # as a patch's length of such updates accumulates; the place is one the search's density reaches beyond the
            # nearest look-alike as good as the truth (:func:`_wrong_place_ms`)
            narrowed = self.searching * share
            self.slip_ms = (self.slipped * self.slip_ms + narrowed * _wrong_place_ms(self.search_ms, self._nearest_m)) / (self.slipped + narrowed)
            self.slipped, self.searching = self.slipped + narrowed, self.searching - narrowed
        # the filters temper each patch by the track run since their last terrain update (the first takes all of it)
        self._untempered_m += model.speed_mps * step
        if on_map:  # off it (or under the patch's least share) there is no update, and no separation to add
            self._evidence += min(1.0, self._untempered_m / model.patch_length_m) * np.nan_to_num(snr, nan=0.0, posinf=0.0)
            self._untempered_m = 0.0
        self.searching = min(self.searching, _still_searching(snr, rivals, self._evidence, lookalike.evidence_scale))
        lose, lose_ms = _loss(snr, distance_m, p, lookalike.evidence_scale)
        gain = _acquisition(rivals, self.slip_ms, lookalike.ring_edges_m) if usable else 0.0
        stay = self.slipped * (1.0 - min(1.0, share * model.acquisitions_per_patch) * gain)
        fresh = max(1.0 - self.searching - self.slipped, 0.0) * share * lose
        self.slip_ms = (stay * self.slip_ms + fresh * (lose_ms + 2.0 * p)) / max(stay + fresh, 1e-300)
        self.slipped = min(stay + fresh, 1.0 - self.searching)
        lost = self.searching + self.slipped
        return lost, (self.searching * self.shown_ms + self.slipped * self.slip_ms) / max(lost, 1e-300)


def predict_along(accuracy: Grid, t: np.ndarray, xy: np.ndarray, model: RouteModel, lookalike: Lookalike | None = None,
                  held: Grid | None = None) -> dict[str, np.ndarray]:
    """The predicted 1-sigma horizontal error at updates at times ``t`` and positions ``xy`` (a track already known).

    Without ``lookalike`` the filter is taken to hold the true position from the start (the bound and the growth
    only); with it, the lock is acquired, lost and regained as the module docstring says, and the result also
    carries ``unlocked`` (the probability of not holding the true position) and ``locked_m`` (the error when holding it).
    With ``held`` (one patch's error with the survey's error alone, :func:`lost.host.plan.accuracy.held_grid`) the error holding the lock is that
    bound where there is one, growing as the density does between (module docstring); without it, the density's own.
    """
    r, c, on_map = _sample(accuracy, _behind(np.asarray(xy, np.float64), model.patch_lag_m))
    fill = _filled(np.asarray(xy, np.float64), model)
    with np.errstate(divide="ignore"):
        thinned = 1.0 / np.sqrt(fill)  # a patch of a fraction of its nodes: its bound that much wider
    on_map = on_map & (fill >= model.min_valid_fraction)  # a patch under this share of its nodes is not correlated
    bound = np.full(len(t), np.inf)
    bound[on_map] = accuracy.depth_m[r[on_map], c[on_map]] * thinned[on_map]
    held_bound = np.full(len(t), np.inf)
    if held is not None:
        held_bound[on_map] = held.depth_m[r[on_map], c[on_map]] * thinned[on_map]
    usable = bound <= model.usable_sigma_m
    rings = None
    if lookalike is not None:
        rings = tuple(np.full((len(lookalike.ring_edges_m), len(t)), np.nan) for _ in range(3))
        for along, grid in zip(rings, (lookalike.snr, lookalike.distance_m, lookalike.rivals)):
            along[:, on_map] = grid[:, r[on_map], c[on_map]]
        rings[0][:] *= fill  # and its separations from the look-alikes (sums over its nodes) that much smaller
    share = min(1.0, model.speed_mps * model.interval_s / model.patch_length_m)  # of a patch new at each update (tempering)
    held_ms = np.empty(len(t))  # horizontal mean square error holding the lock
    error_ms, grown_from, held_since = np.inf, 0.0, 0.0
    unlocked = np.zeros(len(t))
    unlocked_ms = np.zeros(len(t))  # horizontal mean square error while not holding it
    lock = _Lock(model, float(t[0]) if len(t) else 0.0, share)
    lost = _Unlocked(model, lookalike, share) if lookalike is not None else None
    previous = None
    for n, time_s in enumerate(t):
        step = model.interval_s if previous is None else max(time_s - previous, 0.0)
        p = lock.advance(time_s, step, previous is None, bool(usable[n]), bound[n])
        if lost is not None:
            unlocked[n], unlocked_ms[n] = lost.advance(step, p, bool(usable[n]), bool(on_map[n]), *(ring[:, n] for ring in rings))
        previous = time_s
        if usable[n] and np.isfinite(held_bound[n]):
            # the estimate moves the update's gain of the way to this patch's fit; the error it carried keeps the rest,
            # summed as amplitudes (the map's errors under successive patches are the same errors)
            carried = held_bound[n] if not np.isfinite(error_ms) else np.sqrt(held_ms[n - 1])
            error_ms = ((1.0 - lock.gain) * carried + lock.gain * held_bound[n]) ** 2
            grown_from, held_since = 2.0 * p, time_s
        # two bounds on the error held, each from above: the density's width and one patch's bound grown since (by the
        # sensor's own errors where the model knows them, else as the density grew); the lower
        growth = lock.held_growth_ms(time_s - held_since, step) if np.isfinite(error_ms) else None
        growth = max(2.0 * p - grown_from, 0.0) if growth is None else growth
        if model.slant_range:
            growth *= 0.5  # the ship's slant range holds the axis along it: the error held grows across it alone
        held_ms[n] = 2.0 * p if held is None or not np.isfinite(error_ms) else min(error_ms + growth, 2.0 * p)
    predicted = np.sqrt((1.0 - unlocked) * held_ms + unlocked * unlocked_ms)
    result = {"t_s": np.asarray(t), "east_m": xy[:, 0], "north_m": xy[:, 1], "bound_m": bound, "usable": usable, "predicted_m": predicted}
    if rings is not None:
        result.update(unlocked=unlocked, locked_m=np.sqrt(held_ms))
    return result


def _filled(xy: np.ndarray, model: RouteModel) -> np.ndarray:
    """The share of a patch's nodes sounded at each update: a real-time patch (``patch_lag_m`` > 0) holds only the pings
    received since the start, swept by its swath where the model knows it (``sweep``, :func:`lost.host.plan.fill.patch_fill`),
    else taken to fill over its first patch length along the track; any other patch is whole."""
    if model.patch_lag_m <= 0 or len(xy) < 2:
        return np.ones(len(xy))
    if model.sweep is not None:
        return patch_fill(xy, model.interval_s, model.sweep)
    along = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    return np.minimum(along / model.patch_length_m, 1.0)


def _flip(separation: np.ndarray, penalty: np.ndarray | float, scale: float) -> np.ndarray:
    """The probability that a patch prefers a placement of ``separation`` (and a prior ``penalty``, log-odds) over the truth."""
    evidence = separation / scale
    with np.errstate(invalid="ignore", divide="ignore"):
        flip = ndtr(-(evidence / 2.0 + penalty) / np.sqrt(evidence))
    return np.where(np.isinf(evidence), 0.0, np.where(evidence > 0, flip, 0.5))


def _loss(separation: np.ndarray, distance_m: np.ndarray, p: float, evidence_scale: float) -> tuple[float, float]:
    """A lock's hazard of slipping onto a look-alike per patch (capped at 1), and the mean square distance it slips."""
    ok = np.isfinite(separation) & (distance_m > 3.0 * np.sqrt(2.0 * p))
    if not ok.any():
        return 0.0, 0.0
    flips = _flip(separation[ok], distance_m[ok] ** 2 / (2.0 * p), evidence_scale)
    total = float(flips.sum())
    return min(total, 1.0), float(np.sum(flips * distance_m[ok] ** 2) / total) if total > 0 else 0.0


def false_lock_probability(lookalike: Lookalike) -> np.ndarray:
    """At every node, the chance that one patch there prefers a look-alike anywhere within the search radius over the truth
    (the rivals of every ring, capped at 1; NaN where there is no patch): where a filter without a lock locks wrongly,
    or not at all."""
    return np.where(np.isnan(lookalike.rivals).all(axis=0), np.nan, np.minimum(np.nansum(lookalike.rivals, axis=0), 1.0))


def _still_searching(separation: np.ndarray, rivals: np.ndarray, evidence: np.ndarray, scale: float) -> float:
    """The chance that a filter still searching has not found the truth: a look-alike of some ring still ahead of it.

    The evidence against a ring's look-alikes accumulates over the patches seen (``evidence``: the new share of each
    patch times the ring's smallest separation there, a lower bound, as a fixed offset's separation changes along the
    track). The ring holds ``rivals / Phi(-sqrt(snr / c) / 2)`` look-alikes as good as its best (each basin of the
    misfit one; ``c`` the look-alikes' evidence scale, with which ``rivals`` were counted), each still ahead with
    ``Phi(-sqrt(evidence) / 2)``: the accumulated evidence taken at face value, as a Bayesian filter's product of
    likelihoods takes it (no evidence scale: the lower bound already discounts it). Terrain that repeats keeps the
    separation at zero and the search going; rough terrain ends it within a patch length; a hole adds nothing."""
    ok = np.isfinite(separation) & np.isfinite(rivals)
    if not ok.any():
        return 1.0
    best = ndtr(-np.sqrt(separation[ok] / scale) / 2.0)
    count = rivals[ok] / np.maximum(best, 1e-300)
    return float(min(1.0, np.sum(count * ndtr(-np.sqrt(evidence[ok]) / 2.0))))


def _nearest_lookalike(distance_m: np.ndarray, rivals: np.ndarray) -> float:
    """The distance of the nearest ring's best look-alike that is as good as the truth (its ring's rivals at least one
    half: an indistinguishable placement wins a patch with even odds), metres; 0 where no ring holds one."""
    alike = np.isfinite(rivals) & (rivals >= 0.5)
    return float(distance_m[alike][0]) if alike.any() else 0.0


def _wrong_place_ms(search_ms: float, nearest_m: float) -> float:
    """The mean square distance of the wrong place a search narrows onto when the truth's own placement drops out.

    A Bayesian filter with a flat likelihood over the look-alikes keeps the search's density, a Gaussian of
    ``search_ms / 2`` per axis about the truth, on them; look-alikes spread evenly over the plane from the nearest
    one's distance ``r0`` outward take it in proportion to that density. The squared distance of a 2D Gaussian is
    exponential (memoryless), so beyond ``r0`` its mean is ``r0^2 + search_ms``. Without a look-alike as good as the
    truth (``r0`` 0) the wrong place is anywhere in the search's density: ``search_ms``."""
    return nearest_m**2 + search_ms


def _acquisition(rivals: np.ndarray, lost_ms: float, edges_m: np.ndarray) -> float:
    """The chance per patch that a filter not holding the truth finds it: no look-alike within twice its error wins."""
    inner = np.concatenate(([0.0], edges_m[:-1]))
    within = np.isfinite(rivals) & (inner <= 2.0 * np.sqrt(lost_ms))
    return float(max(0.0, 1.0 - np.sum(rivals[within])))
