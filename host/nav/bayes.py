"""What the point-mass and the particle filter share: a record's measurements, gated, counted and staged.

A filter holds its density as candidate positions with probabilities (cells or particles). This base
class turns an observation into log-likelihoods at those candidates (sonar patch, single depth, slant
range; :mod:`lost.host.nav.likelihood`), refuses what :mod:`lost.host.nav.trust` says to refuse, and
multiplies the rest in (Nygren eq. 3.5). A subclass says how its density is held: where its candidates
are, how a likelihood reweighs them, what accepting a posterior does to it, and how it re-initializes.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import chi2

from ..grid import Grid
from .estimator import Estimate, Observation
from .likelihood import TerrainLikelihood
from .moments import quadratic_form_2x2
from .trust import Trust, nis

__all__ = ["BayesFilter", "RANGE_GATE", "ring_log_likelihood"]

#: The slant range's innovation gate: chi-square with one degree of freedom at 99.9 %.
RANGE_GATE = float(chi2.ppf(0.999, 1))


def ring_log_likelihood(residual_m: np.ndarray, sigma_m: float, half_width_m: float, dof: float = math.inf) -> np.ndarray:
    """Log-likelihood of a range's residual (a candidate's range less the measured) for cells of ``half_width_m``.

    Where a cell is no wider than the range's sigma, the Gaussian at its centre. Where it is wider, the
    grid cannot hold what a range says within a cell: every cell the ring passes through keeps its mass
    (a flat top ``half_width_m`` wide, Gaussian beyond), and only the cells it misses are ruled out.
    Read at the centres, a 3 m ring across 25 m cells keeps the cells it crosses near their centres
    and, range after range, empties the ones it crosses off-centre: on ``offset`` (terrain seed 13) the
    true place's cells lost a factor of 500 in 8 ranges to places 200 m along the ring, and the search
    locked there. An average over the cell does not stop that (it compounds, range after range). The
    grid narrows to cells finer than the ring once the terrain has spoken.

    ``dof`` finite: beyond the flat top a Student-t of that many degrees of freedom, ``sigma_m`` its scale.
    """
    r = np.abs(np.asarray(residual_m, float))
    if half_width_m > sigma_m:
        r = np.maximum(r - half_width_m, 0.0)
    return _log_kernel((r / sigma_m) ** 2, dof, 1)


def _log_kernel(q: np.ndarray, dof: float, dimensions: int) -> np.ndarray:
    """The log-density, up to a constant, of a measurement whose squared Mahalanobis distance is ``q``: a Student-t of
    ``dof`` degrees of freedom in ``dimensions`` (the Gaussian where ``dof`` is infinite)."""
    return -0.5 * q if math.isinf(dof) else -0.5 * (dof + dimensions) * np.log1p(q / dof)


class BayesFilter:
    """The measurement side of a recursive Bayesian terrain filter (see the module docstring).

    Parameters
    ----------
    likelihood : TerrainLikelihood
        Patch, depth and (through the filter) range likelihoods against the map.
    params : NavParameters
        The noise levels and the trust rules.
    grid : Grid
        The map (for its node spacing).
    name : str
        The filter's name in the outputs.
    """

    def __init__(self, likelihood: TerrainLikelihood, params, *, grid: Grid, name: str) -> None:
        self.name = name
        self._lik = likelihood
        self._p = params
        self._trust = Trust(params, node_m=grid.node_m)
        self.counts = self._trust.counts
        node_part = (params.position_floor_nodes * grid.node_m) ** 2
        self._floor_var_acquisition = node_part + params.position_floor_m**2
        self._floor_var_tracking = node_part + self._tracking_floor_m(params) ** 2
        # The point form's depth bias: a mean per candidate (the subclass keeps it aligned) and a shared variance.
        self._depth_bias: np.ndarray = np.zeros(1)
        self._depth_bias_var = params.depth_bias_sigma_m**2
        self._stage, self._nis, self._rejected = "uninitialized", float("nan"), ""
        self._layback: np.ndarray | None = None

    def _search_prior(self) -> tuple[np.ndarray, float | None]:
        """Where a re-initialized search is centred, and its prior's sigma (None: flat, the ML mode of section 5).

        A towed vehicle has an anchor that does not drift: the cable model's lay-back position. The
        search is then laid as the first one was, a Gaussian of ``initial_sigma_m`` around it; a flat
        search over kilometres finds the terrain's best match anywhere on the slant range's ring (on
        ``offset``, 900 m off on the ship's far side, which ranges and terrain both accepted for
        minutes). Without a lay-back, the search is flat around the estimate.

        The cable model's straight line is wrong in a turn (on ``two_hour`` the lay-back lies 1.8 km from the
        vehicle there). When the patches fit better elsewhere, that place lies within ``lookalike_radius_m`` of
        the estimate; a search around a lay-back farther from the estimate than the search's own half width
        (``pmf_sigmas`` initial sigmas) would not hold it, so the search is the same Gaussian around the estimate
        (``two_hour`` seed 0: from 145 m off in a turn, around the lay-back the PMF re-initialized six more times
        up to 1.9 km off; around the estimate it is back within 10 m).
        """
        if self._layback is None:
            return self._moments()[0], None
        if self._trust.restart_cause == "fits_better_elsewhere":
            estimate = self._moments()[0]
            if np.hypot(*(self._layback - estimate)) > self._search_half_m:
                return estimate, self._p.initial_sigma_m
        return self._layback.copy(), self._p.initial_sigma_m

    @property
    def _search_half_m(self) -> float:
        """The half width of a (re)started search, either filter's: ``pmf_sigmas`` initial sigmas."""
        return self._p.pmf_sigmas * self._p.initial_sigma_m

    @property
    def _floor_var(self) -> float:
        """The density's least variance, each axis: wide while acquiring, the tracking floor once settled.

        Before it is usable a filter has not learned its misfit level nor its velocity bias, and a
        narrow density would commit to a neighbouring peak of the likelihood (on ``short``, 8-20 m
        off for two minutes); once usable, the wide floor would only misstate its precision (NEES
        mostly below its band). A look-alike check lowers the usable flag but teaches nothing wrong,
        so only a refused update or a re-initialization brings the wide floor back (``Trust.settled``;
        on ``two_hour``'s smooth east, 1,791 look-alike updates had the wide floor, NEES in band 0.77).
        """
        return self._floor_var_tracking if self._trust.settled else self._floor_var_acquisition

    # -- what a subclass provides ---------------------------------------------------------------------

    @staticmethod
    def _tracking_floor_m(params) -> float:
        """The metres part of the settled filter's floor (see NavParameters)."""
        return params.position_floor_tracking_m

    def _candidates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (x, y) of the density's candidates and their probabilities, all one shape."""
        raise NotImplementedError

    def _spacing(self) -> float:
        """The candidates' typical spacing, metres."""
        raise NotImplementedError

    def _cell_half_width(self) -> float:
        """Half the side of the square a candidate's mass is spread over, metres: none for a point."""
        return 0.0

    def _moments(self) -> tuple[np.ndarray, np.ndarray]:
        """Mean and covariance of the density."""
        raise NotImplementedError

    def _reweigh(self, log_likelihood: np.ndarray) -> tuple[object, np.ndarray, np.ndarray] | None:
        """The posterior a likelihood would give (opaque to this class) with its mean and covariance; None on underflow."""
        raise NotImplementedError

    def _accept(self, posterior: object, post_cov: np.ndarray, correction_m: np.ndarray, terrain: bool, floored: bool = True) -> None:
        """Make ``posterior`` the density (the gates have passed); ``floored``: the update owes the density its floor
        (:meth:`_owes_floor`)."""
        raise NotImplementedError

    @staticmethod
    def _owes_floor(terrain: bool, kind: str) -> bool:
        """Whether an update owes the density its floor: a terrain match or a position fix does, a slant range does not.

        The floor stands for errors the likelihoods do not hold (the matches' correlated error, a fix's cast). A range
        holds one axis, the one along it, to a metre or two; owed after it, the floor's shortfall on that axis was
        blurred into the cross-track axis as well at every record, on the map and off it (``coarse_map_900s`` seed 0: the
        PMF's sigma 17 m north around a 3 m error; off the map it grew to 70 m and the mean wandered 25 m with it). Not
        owed there, the NEES rose on every case and the false fixes went; the RMS fell on the smooth floors and rose 4-9 %
        on the rough ones (ten seeds a case: docs/nav.md, "The point-mass filter").
        """
        return terrain or kind != "range"

    def _reinitialize(self) -> None:
        """Widen the search around the estimate, flat (see the trust rules)."""
        raise NotImplementedError

    # -- the shared update ------------------------------------------------------------------------------

    def update(self, observation: Observation) -> None:
        if observation.layback_m is not None:
            self._layback = observation.layback_m
        if observation.patch is not None and self._p.matching == "patch":
            self._terrain_update(observation)
        elif self._p.matching == "point" and math.isfinite(observation.ocean_depth_m):
            self._depth_update(observation.ocean_depth_m)
        fixed = self._p.use_usbl_fix and observation.fix_position_m is not None and self._fix_update(observation)
        if self._p.use_slant_range and math.isfinite(observation.slant_range_m) and observation.frame is not None:
            if fixed:
                # The fix's range along the line of sight is this travel time's: one measurement is not used twice.
                self.counts["range_in_fix"] += 1
            else:
                self._range_update(observation)
        self._trust.watch(self._moments()[1])

    def _patch_shift(self, age_s: float) -> tuple[np.ndarray | float, np.ndarray | float]:
        """Where a candidate's patch truly lies, less where it was reckoned: the velocity bias times the patch's age.

        The patch's soundings were placed ``age_s`` back by the measured velocity, which runs ahead of the
        true one by the bias b: they lie b * age further along than reckoned (east, north). The particles
        move each patch by their own bias, the point-mass filter by its estimate.
        """
        raise NotImplementedError

    @property
    def velocity_bias_mps(self) -> np.ndarray:
        """The velocity-bias estimate (east, north), m/s: the measured velocity less the true."""
        raise NotImplementedError

    @property
    def velocity_bias_sigma_mps(self) -> np.ndarray:
        """Its 1-sigma each axis, m/s (NaN where it is not estimated)."""
        raise NotImplementedError

    def _before_patch(self, patch, weight: float) -> None:
        """A hook before a patch is weighed: a particle cloud may redraw itself where the patch fits."""

    def _terrain_update(self, observation: Observation) -> None:
        patch = observation.patch
        length = max(patch.depth_m.shape) * patch.node_m
        weight = self._trust.patch_weight(length, self._moments()[1])
        self._before_patch(patch, weight)
        x, y, mass = self._candidates()
        shift_x, shift_y = self._patch_shift(patch.age_s)
        result = self._lik.patch(x + shift_x, y + shift_y, patch, weight=weight, sigma_scale=self._trust.misfit_level,
                                 spacing_m=self._spacing())
        if result is None or result.valid_nodes < self._p.min_valid_fraction * patch.depth_m.size:
            self.counts["patch_too_sparse"] += 1
            return
        if not result.informative.any():
            self._no_information("patch_on_holes" if result.on_holes else "patch_off_map")
            return
        on_map = float(mass[result.informative].sum())
        # Holes count as the edge does: where the truth's soundings fall on holes its placement is unknown, and the
        # valid ones beside it would pull the density (a 30 m wide density beside a hole band went 62 m off, usable).
        if self._trust.at_edge(on_map, self._moments()[1]):
            self._no_information("patch_at_map_edge")
            return
        # A patch that fits nowhere is refused only where the map covers most of where the vehicle may be.
        if self._trust.misfit_refused(result.misfit) and on_map > 0.5:
            self._reject("misfit", terrain=True)
            return
        if self._apply(result.log_likelihood, terrain=True):
            self._trust.note_misfit(result.misfit)
            mean, cov = self._moments()
            # One shift for the point-mass filter's cells, one per particle: their mean by the density's mass.
            shift = [float(s) if np.ndim(s) == 0 else float(np.ravel(s) @ np.ravel(mass)) / float(mass.sum()) for s in (shift_x, shift_y)]
            self._trust.note_independence(self._lik, mean + shift, cov, patch)
            if self._trust.look_alike(self._lik, mean + shift, cov, patch):
                self._reinitialize()
                self._stage = "reinitialized"
                return
            self._stage = "tracking" if self._trust.usable else "acquisition"

    def _depth_update(self, ocean_depth_m: float) -> None:
        """The single-depth form with its depth bias, Rao-Blackwellized: each candidate's own bias estimate.

        Measured minus map is bias plus noise. Given a candidate's history the bias is linear-Gaussian,
        so each candidate carries the mean of a scalar Kalman filter on it (``_depth_bias``, the shape
        of the candidates; the variance ``_depth_bias_var`` is the same for all, their measurements
        being alike): the candidate is weighed by its innovation against that variance plus the
        measurement's, and its bias mean moves by the gain. Off the map: the expected value at the
        truth (-1/2), no bias update.
        """
        x, y, _ = self._candidates()
        residual, informative = self._lik.depth_residual(x, y, ocean_depth_m)
        if not informative.any():
            self._no_information("depth_off_map")
            return
        variance = self._lik.depth_sigma_m**2 + self._depth_bias_var
        innovation = residual - self._depth_bias
        ell = np.where(informative, -0.5 * innovation**2 / variance, -0.5)
        before = self._depth_bias
        gain = self._depth_bias_var / variance
        self._depth_bias = proposed = np.where(informative, before + gain * innovation, before)
        if self._apply(ell * self._p.likelihood_weight, terrain=True):
            self._depth_bias_var *= 1.0 - gain
        elif self._depth_bias is proposed:  # refused, and not re-initialized (which lays biases of its own)
            self._depth_bias = before

    @property
    def depth_bias_m(self) -> tuple[float, float]:
        """The single-depth form's depth-bias estimate (measured minus map), metres, and its 1-sigma."""
        _, _, mass = self._candidates()
        mean = float(np.sum(mass * self._depth_bias) / np.sum(mass))
        spread = float(np.sum(mass * (self._depth_bias - mean) ** 2) / np.sum(mass))
        return mean, math.sqrt(self._depth_bias_var + spread)

    def _range_update(self, observation: Observation) -> None:
        frame = observation.frame
        vertical = observation.vehicle_depth_m - self._p.reference_depth_m
        horizontal_sq = observation.slant_range_m**2 - vertical**2
        if not (math.isfinite(horizontal_sq) and horizontal_sq > 0):
            self.counts["range_shorter_than_depth"] += 1
            return
        horizontal = math.sqrt(horizontal_sq)
        innovation = self._range_innovation_nis(frame, horizontal)
        # While usable the stated variance is the floor's and the worst geometry's: the gate takes what the ranges
        # showed (learned over every range, so that it is there when the flag first rises). While acquiring the
        # density's own spread is real, and a scaled gate would refuse the ranges that must move it (each refusal
        # counts toward a re-initialization by ranges).
        scale = self._trust.note_range_innovation(innovation)
        if innovation > RANGE_GATE * (scale if self._trust.usable else 1.0):
            self._reject("innovation", terrain=False)
            return
        x, y, _ = self._candidates()
        distance = np.hypot(x - frame.ship_x_m, y - frame.ship_y_m)
        # A t only while usable: a narrow density is where a range 3-4 sigma off (a ray bent by a cast not known) would
        # move it far; while acquiring the ring must rule places out.
        dof = self._p.slant_range_dof if self._trust.usable else math.inf
        self._apply(ring_log_likelihood(distance - horizontal, self._p.slant_range_sigma_m, self._cell_half_width(), dof), terrain=False)

    def _range_innovation_nis(self, frame, horizontal_m: float) -> float:
        """The range's innovation squared over its variance, linearized at the density's mean (chi-square, 1 dof).

        The moment NIS of ``_apply`` understates a far outlier: a density cannot move to a ring far
        from itself, so it shifts a little toward it and the shift looks modest (slant ranges 25-190 m
        off passed it on the shipped tows, each a false fix). This is the extended Kalman filter's gate.
        """
        mean, cov = self._moments()
        line = mean - np.array([frame.ship_x_m, frame.ship_y_m])
        predicted = float(np.hypot(*line))
        if predicted <= 0.0:
            return 0.0
        direction = line / predicted
        variance = float(direction @ cov @ direction) + self._p.slant_range_sigma_m**2
        return (horizontal_m - predicted) ** 2 / variance

    def _fix_update(self, observation: Observation) -> bool:
        """The USBL fix as a position measurement with its covariance, gated like a range; True when used.

        Read as a Student-t of ``usbl_fix_dof`` degrees of freedom with the fix's covariance as its scale: a fix three
        or four times its sigma off (multipath, a refraction the processing's cast does not hold) pulls a density far
        less than a Gaussian's would, and one near the density counts about as much. The fix's innovation NIS,
        ``(z - m)' (P + R)^-1 (z - m)`` with the density's moments, is gated first (``gate_nis``; while usable scaled by
        what the fixes showed, ``Trust.note_fix_innovation``): a particle cloud cannot represent a posterior far from
        itself, so the moment NIS of ``_apply`` alone would understate a far outlier (a multipath reply).
        """
        mean, cov = self._moments()
        fix, fix_cov = observation.fix_position_m, observation.fix_covariance_m2
        innovation = fix - mean
        value = quadratic_form_2x2(innovation, cov + fix_cov)
        # While usable the gate takes what the fixes showed (learned over every fix, as the ranges' gate is).
        scale = self._trust.note_fix_innovation(value)
        if value > self._p.gate_nis * (scale if self._trust.usable else 1.0):
            self._reject("gate", False, "fix")
            return False
        x, y, _ = self._candidates()
        dx, dy = x - fix[0], y - fix[1]
        info = np.linalg.inv(fix_cov)
        q = info[0, 0] * dx * dx + 2.0 * info[0, 1] * dx * dy + info[1, 1] * dy * dy
        return self._apply(_log_kernel(q, self._p.usbl_fix_dof, 2), terrain=False, kind="fix")

    def _no_information(self, reason: str) -> None:
        self.counts[reason] += 1
        self._stage = "off_map"
        self._trust.no_information()

    def _apply(self, log_likelihood: np.ndarray, *, terrain: bool, kind: str = "range") -> bool:
        """Multiply a likelihood in, gated by its NIS; counts and stages follow. True when it was used.

        ``kind`` names a non-terrain measurement in the counts: ``"range"`` or ``"fix"`` (a USBL fix).
        """
        prior_mean, prior_cov = self._moments()
        proposal = self._reweigh(log_likelihood)
        if proposal is None:
            self._reject("underflow", terrain, kind)
            return False
        posterior, post_mean, post_cov = proposal
        value = nis(prior_mean, prior_cov, post_mean, post_cov)
        if terrain:
            self._nis = value
        if value > self._p.gate_nis:
            self._reject("gate", terrain, kind)
            return False
        self._accept(posterior, post_cov, post_mean - prior_mean, terrain, self._owes_floor(terrain, kind))
        if terrain:
            self._trust.note_correction(post_mean - prior_mean, prior_cov, post_cov)
            self._trust.accepted(post_cov)
            self._stage = "tracking" if self._trust.usable else "acquisition"
            self.counts["terrain_updates"] += 1
        else:
            self.counts[f"{kind}_updates"] += 1
            if kind == "range":
                self._trust.range_outcome(refused=False)
            else:
                self._trust.position_fixed()
        return True

    def _reject(self, reason: str, terrain: bool, kind: str = "range") -> None:
        label = reason if terrain or kind == "range" else f"{kind}_{reason}"
        self._rejected = label if not self._rejected else f"{self._rejected},{label}"
        if not terrain:
            self.counts[f"{kind}_rejected_{reason}"] += 1
            # A refused range or a run of refused fixes may say the terrain holds the density on a wrong place.
            if self._trust.range_outcome(refused=True) if kind == "range" else self._trust.fix_refused():
                self._reinitialize()
                self._stage = "reinitialized"
            return
        self._stage = "rejected"
        if self._trust.rejected(reason):
            self._reinitialize()
            self._stage = "reinitialized"

    def _moved(self, dt_s: float, distance_m: float) -> None:
        """After a prediction: error growth and tempering advance, the record's stage starts afresh."""
        self._trust.moved(dt_s, distance_m)
        self._stage, self._nis, self._rejected = "dead_reckoning", float("nan"), ""

    def estimate(self) -> Estimate:
        mean, cov = self._moments()
        bias = self.depth_bias_m[0] if self._p.matching == "point" else float("nan")
        return Estimate(position=mean, covariance=cov, usable=self._trust.usable, stage=self._stage, nis=self._nis, rejected=self._rejected,
                        depth_bias_m=bias, velocity_bias_mps=tuple(self.velocity_bias_mps),
                        velocity_bias_sigma_mps=tuple(self.velocity_bias_sigma_mps),
                        reinitialized=self._trust.restart_cause if self._stage == "reinitialized" else "")
