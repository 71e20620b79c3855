"""What makes a Bayesian filter's estimate trustworthy: error growth, tempering, gating, the usable flag, recovery.

These rules are shared by the point-mass and the particle filter, and kept as named parameters of
:class:`~lost.host.nav.parameters.NavParameters`, as MB-System's TRN keeps its reinitialization rules.

- Error growth (Nygren section 6): between terrain updates the position error grows by the velocity
  noise of each step and by the INS error model of eqs. 6.1-6.2 over the time since the last update
  (a terrain update or a USBL fix).
- Tempering: each patch's log-likelihood is weighted by the share of the patch that is new since the
  last update used (see :mod:`lost.host.nav.likelihood`).
- Correlated residuals: each patch's log-likelihood is also multiplied by the share of its nodes whose
  residuals are independent (N_eff / n; ``temper_by_correlation``), the running median of that share
  measured at the estimate over the last ``MISFIT_MEMORY`` accepted patches while the density is narrow
  (under twice the usable width: elsewhere the residual is the terrain's mismatch, not the map's error).
  Until it is measured, 1.
- Residual level: the misfit of a patch is its best mean absolute residual over the filter's area in
  units of the residual the nominal sigma predicts (about 1 at the true position). The running
  median of the accepted patches' misfits (the last ``MISFIT_MEMORY``, bounded to [0.5, 4]) scales
  the likelihood's sigma: the real map error is seldom known, and this learns it from the data.
- Gating: an update is refused when the patch fits nowhere in the filter's area (its misfit over
  the running level exceeds ``misfit_gate``), or when it
  moves the estimate further than its own information allows: the normalized innovation squared
  ``NIS = d^T (P_prior - P_post)^-1 d``, d the shift of the mean, is chi-square with 2 degrees of freedom
  for a consistent linear-Gaussian update (there d = K nu and Cov(d) = P_prior - P_post).
- Usable: the largest 1-sigma axis of the covariance stays under ``usable_sigma_nodes`` map nodes for
  ``usable_updates`` terrain updates in a row (``usable_updates_point`` for the single-depth form;
  MB-System: under a threshold for 200 updates). A
  multimodal posterior has a wide covariance, so look-alike terrain lowers the flag by itself. A
  refused terrain update lowers it, and so do three refused slant ranges among the last ten (one
  is an outlier, several say the estimate has moved away from the range). Settled: the filter has
  been usable since its last (re)start and no terrain update has been refused since, so its misfit
  level and velocity bias are learned; a look-alike or a covariance grown on smooth ground lowers the
  usable flag, not this (it chooses the density's floor, see ``BayesFilter._floor_var``). Drift: each
  accepted terrain update's shift of the mean d has covariance ``P_prior - P_post`` when the filter is
  consistent, so the sum of the last ``usable_updates`` shifts against the sum of those covariances is
  chi-square with 2 degrees of freedom; above ``drift_gate`` the updates keep pulling one way, the density
  trails the truth (an unlearned velocity error: a towfish lagging the ship whose velocity it is given)
  and the flag stays down (``corrections_drifting``); so does the trail test on the same window (most shifts one way
  along an axis, their steady-state lag beyond two of the density's sigmas: ``corrections_one_way``). Look-alike terrain: a
  density can collapse onto one of several equally good modes (particles by resampling, cells by
  their offsets), so once the covariance is small enough to be usable, each patch is also matched
  over ``lookalike_radius_m`` around the estimate; if a placement beyond three sigma fits within
  ``lookalike_margin`` (mean absolute residual over sigma, per node) of the best near the estimate,
  the update is counted ``lookalike`` and the flag goes down.
- Wrong place: the same check measures whether a placement beyond three sigma fits *better* than the
  best near the estimate by more than ``elsewhere_margin`` over the square root of the independent share
  (the margin's noise grows as the residuals' correlation; counted ``fits_better_elsewhere``). A density
  that locked onto a wrong place learns that place's misfit as its running level, so the misfit gate no
  longer refuses it; ``reinit_after`` such patches among the last ``2 reinit_after`` checked re-initialize
  the filter (``reinitialized_elsewhere``).
- The map's edge: a patch whose placements hang past the map carries no information, and the
  candidates beside it on the map all fit it a little worse than the truth would; so while the
  density is narrow (under twice the usable width) and less than ``EDGE_MASS`` of it lies where the
  patch is wholly on the map, or wider and less than ``WIDE_EDGE_MASS``, the patch is left out
  (``patch_at_map_edge``) and the filter dead-reckons.
  Off the map or at its edge, the filter is no longer usable once it has had neither a terrain update
  nor a position fix for ``off_map_usable_s`` (``unusable_off_map``): dead reckoning is not a terrain fix.
- Slant ranges and USBL fixes: the gates of a usable filter are scaled by how far the innovations fall under their stated
  variance (``Trust.note_range_innovation``, ``Trust.note_fix_innovation``; :mod:`lost.host.nav.gate`), so that an
  outlier of a few metres is not taken by a narrow density.
- Recovery: when ``reinit_after`` of the last ``2 reinit_after`` terrain updates were refused the
  filter re-initializes, its search widened to ``initial_sigma_m`` around its current estimate
  (a window rather than a run, so that a chance fit at the wrong place does not reset the count).
  Not on a return to the map: after ``off_map_usable_s`` without terrain (off the map, at its edge,
  over holes, without patches) a density that has taken terrain since its (re)start is dead reckoning's,
  shaped by no terrain since, and a refused update says the terrain and the dead reckoning disagree,
  not that a lock went wrong. Until the next accepted terrain update (``returned_after_refusals``) such
  refusals are counted (``refused_on_return``) and lower the usable flag, but re-initialize nothing:
  the density keeps widening by dead reckoning until the terrain's correction passes the gate (a
  density that left the map wrong comes back wide enough to take it). On ``two_hour`` (seed 0) ten
  refusals of a right density, back from 583 s beside a hole, re-initialized it around a lay-back
  1.8 km off in the ship's turn.
  So does ``2 reinit_after`` slant ranges refused in a row: the terrain holds the density where
  every range says it is not (``reinitialized_by_ranges``); and ``2 reinit_after`` USBL fixes refused in a
  row (``reinitialized_by_fixes``): a density locked narrow on a wrong place gates out every fix.
"""

from __future__ import annotations

import math
import statistics
from collections import Counter, deque

import numpy as np

from .gate import CHI2_1_MEDIAN, CHI2_2_MEDIAN, LearnedGate
from .moments import eigenvalues_2x2, largest_sigma, quadratic_form_2x2

__all__ = ["SCHULER_PERIOD_S", "MISFIT_MEMORY", "RESTART_CAUSES", "ins_position_sigma", "nis", "Trust"]

#: Accepted patches whose misfits set the running residual level.
MISFIT_MEMORY = 50
#: One accepted narrow patch in this many measures its independent share (``Trust.note_independence``).
SHARE_EVERY = 5
#: A narrow density with less than this share on the map straddles its edge.
EDGE_MASS = 0.9
#: A wide density with less than this share on the map straddles its edge.
WIDE_EDGE_MASS = 0.5
#: The share of the drift window's shifts one way along an axis that says they trail (25 of 30: a sign test at
#: p = 1.6e-4 per axis and side for shifts that are equally likely either way).
ONE_WAY_SHARE = 5.0 / 6.0
#: The least window (``usable_updates``) over which the sign test has the power to speak (17 of 20 one way: p = 1.3e-3).
TRAIL_WINDOW_MIN = 20
#: A density whose steady-state lag behind the truth (``Trust._one_way``) exceeds this many of its sigmas trails it.
TRAIL_SIGMAS = 2.0

#: Why a filter re-initialized (``Estimate.reinitialized``), by the count that names it.
RESTART_CAUSES = {
    None: "updates_refused",                            # reinit_after of the last 2 reinit_after terrain updates refused
    "reinitialized_elsewhere": "fits_better_elsewhere",  # the patches fit better far from the estimate
    "reinitialized_by_ranges": "ranges_refused",        # 2 reinit_after slant ranges refused in a row
    "reinitialized_by_fixes": "fixes_refused",          # 2 reinit_after USBL fixes refused in a row
}

#: Nygren section 6.1.
SCHULER_PERIOD_S = 84.4 * 60.0
GRAVITY_MPS2 = 9.81


def ins_position_sigma(t_s: float | np.ndarray, *, gyro_bias_rps: float, accel_bias_mps2: float) -> np.ndarray:
    """1-sigma position error of a free INS after ``t_s`` seconds, Nygren eq. 6.2 (one horizontal axis).

    ``gyro_bias_rps`` and ``accel_bias_mps2`` are the RMS gyro and accelerometer biases, rad/s and m/s**2.
    """
    t = np.asarray(t_s, float)
    w = 2.0 * math.pi / SCHULER_PERIOD_S
    wt = np.maximum(w * t, 1e-12)
    gyro = GRAVITY_MPS2 * t / w**2 * (1.0 - np.sin(wt) / wt)
    accel = (1.0 - np.cos(wt)) / w**2
    return np.sqrt((gyro * gyro_bias_rps) ** 2 + (accel * accel_bias_mps2) ** 2)


def nis(prior_mean: np.ndarray, prior_cov: np.ndarray, post_mean: np.ndarray, post_cov: np.ndarray) -> float:
    """Normalized innovation squared of an update from its prior and posterior moments (see the module)."""
    d = post_mean - prior_mean
    # The information an update brings is at least a little in every direction it moves the estimate.
    gain = prior_cov - post_cov + 1e-6 * np.trace(prior_cov) * np.eye(2)
    if eigenvalues_2x2(gain)[0] > 0:
        return quadratic_form_2x2(d, gain)
    # A posterior wider than its prior (a density split between places) has no such bound: measure
    # the shift against the prior alone, a lower bound of the NIS above.
    return quadratic_form_2x2(d, prior_cov)


def _drift_covariance(prior_cov: np.ndarray, post_cov: np.ndarray) -> np.ndarray:
    """The covariance of a consistent update's shift of the mean, ``P_prior - P_post`` (the prior's where that is not positive)."""
    expected = prior_cov - post_cov + 1e-6 * np.trace(prior_cov) * np.eye(2)
    return expected if eigenvalues_2x2(expected)[0] > 0 else prior_cov


class Trust:
    """A filter's bookkeeping of error growth, tempering, the usable flag and recovery.

    Parameters
    ----------
    params : NavParameters
        The named rules (see the module docstring).
    node_m : float
        The map's node spacing (the usable threshold is in nodes).
    """

    def __init__(self, params, *, node_m: float) -> None:
        self._p = params
        self._node_m = float(node_m)
        self.counts: Counter = Counter()
        self.since_update_s = 0.0
        self.travelled_m = math.inf  # the first patch is wholly new
        self.outcomes: deque[bool] = deque(maxlen=2 * params.reinit_after)  # True: refused
        self.good_in_row = 0
        self.usable = False
        self._ranges: deque[bool] = deque(maxlen=10)  # True: refused
        self._ranges_refused_in_row = 0
        self._fixes_refused_in_row = 0
        self._elsewhere: deque[bool] = deque(maxlen=2 * params.reinit_after)  # True: a better fit far off
        self._misfits: deque[float] = deque(maxlen=MISFIT_MEMORY)
        self.misfit_level = 1.0
        self._shares: deque[float] = deque(maxlen=MISFIT_MEMORY)
        self.independent_share = 1.0
        self._usable_share = 0.0  # the independent share when the flag was last up (the wrong-place threshold's)
        self._narrow_patches = 0
        self.settled = False
        self._range_gate = LearnedGate(CHI2_1_MEDIAN)
        self._fix_gate = LearnedGate(CHI2_2_MEDIAN)
        # The drift window, one row an accepted terrain update: shift (2), its expected covariance (xx, xy, yy), gain (2).
        self._corrections = np.zeros((max(int(params.usable_updates), 1), 7))
        self._n_corrections = 0
        self._last_post_var = np.zeros(2)
        self.drift = float("nan")
        self.trailing = False
        self.restart_cause = ""  # the last re-initialization's, one of RESTART_CAUSES' values
        self.since_terrain_s = 0.0  # since the last terrain update taken or refused
        self._took_terrain = False  # a terrain update was taken since the (re)start
        self.returning = False  # a refusal came after off_map_usable_s without terrain; no terrain update taken since

    def misfit_refused(self, misfit: float) -> bool:
        """Whether a patch's misfit is too large for the running residual level."""
        return misfit > self._p.misfit_gate * self.misfit_level

    def note_misfit(self, misfit: float) -> None:
        """An accepted patch's misfit joins the running level."""
        if math.isfinite(misfit):
            self._misfits.append(misfit)
            self.misfit_level = min(max(statistics.median(self._misfits), 0.5), 4.0)  # statistics: a few values, every record

    def note_independence(self, likelihood, mean: np.ndarray, covariance: np.ndarray, patch) -> None:
        """An accepted patch's independent share at the estimate joins the running median, while the density is narrow."""
        if not self._p.temper_by_correlation or self.sigma_max(covariance) > 2.0 * self._p.usable_sigma_nodes * self._node_m:
            return
        self._narrow_patches += 1
        if (self._narrow_patches - 1) % SHARE_EVERY:
            return  # successive patches overlap: one in SHARE_EVERY measures the level as well, at a fraction of the work
        share = likelihood.independent_share(mean, patch)
        if math.isfinite(share):
            self._shares.append(share)
            self.independent_share = float(statistics.median(self._shares))

    def growth_variance(self, dt_s: float) -> float:
        """Variance (m**2, per axis) the position error gains over one step of ``dt_s``."""
        p = self._p
        before = ins_position_sigma(self.since_update_s, gyro_bias_rps=p.gyro_bias_rps, accel_bias_mps2=p.accel_bias_mps2)
        after = ins_position_sigma(self.since_update_s + dt_s, gyro_bias_rps=p.gyro_bias_rps, accel_bias_mps2=p.accel_bias_mps2)
        return (p.velocity_noise_mps * dt_s) ** 2 + float(after**2 - before**2)

    def moved(self, dt_s: float, distance_m: float) -> None:
        self.since_update_s += dt_s
        self.since_terrain_s += dt_s
        self.travelled_m += distance_m

    def patch_weight(self, patch_length_m: float, covariance: np.ndarray) -> float:
        """Tempering weight of the next patch: the share of it that is new, times ``likelihood_weight``, and while the
        density is wider than the usable width, times the patch's independent share."""
        share = self.independent_share if self.sigma_max(covariance) > self._p.usable_sigma_nodes * self._node_m else 1.0
        return self._p.likelihood_weight * share * min(1.0, self.travelled_m / patch_length_m)

    def no_information(self) -> None:
        """A record whose terrain said nothing (off the map, at its edge): the flag drops after ``off_map_usable_s``
        without a terrain update or a position fix."""
        if self.usable and self.since_update_s > self._p.off_map_usable_s:
            self.usable = False
            self.good_in_row = 0
            self.counts["unusable_off_map"] += 1

    def position_fixed(self) -> None:
        """A position fix (a USBL fix) was used: the INS error model's growth restarts from it.

        Without it the growth ran on from the last terrain update: 15 minutes off the map it was
        tens of metres per step, so each fix was taken almost whole and the estimate followed the
        fixes' noise (``usbl_nav`` off its map: 4.5 m RMS, against LOST's 2.5 m; 1.7 m with it).
        """
        self.since_update_s = 0.0
        self._fixes_refused_in_row = 0

    def fix_refused(self) -> bool:
        """A USBL fix was refused; True: re-initialize now (``2 reinit_after`` in a row).

        A fix is independent of the terrain, so a run of them refused says the density is locked where the
        vehicle is not (measured: served ``usbl_nav``, seed 3, the PMF and PF held 71 and 77 m off with NEES 20
        and refused every fix). One refused fix (a multipath reply) changes nothing.
        """
        self._fixes_refused_in_row += 1
        if self._fixes_refused_in_row >= 2 * self._p.reinit_after:
            self._restart("reinitialized_by_fixes")
            return True
        return False

    def note_correction(self, shift_m: np.ndarray, prior_cov: np.ndarray, post_cov: np.ndarray) -> float:
        """A terrain update's shift of the mean and its expected covariance join the drift test; the drift statistic.

        Each shift d of a consistent update is zero-mean with covariance ``P_prior - P_post`` (see :func:`nis`);
        the sum of the last ``usable_updates`` shifts against the sum of their covariances is chi-square with 2
        degrees of freedom. A density that trails the truth (an unlearned velocity error) is pulled the same way
        update after update: each shift is modest, their sum is not.
        """
        d = np.asarray(shift_m, float)
        expected = _drift_covariance(prior_cov, post_cov)
        gain = [1.0 - post_cov[k, k] / max(prior_cov[k, k], 1e-12) for k in (0, 1)]
        window = self._corrections
        window[self._n_corrections % len(window)] = (d[0], d[1], expected[0, 0], expected[0, 1], expected[1, 1], gain[0], gain[1])
        self._n_corrections += 1
        self._last_post_var = np.array([post_cov[0, 0], post_cov[1, 1]], float)
        if self._n_corrections < len(window):
            self.drift, self.trailing = float("nan"), False
            return self.drift
        sums = window.sum(axis=0)
        self.trailing = self._one_way(sums)
        tx, ty, sxx, sxy, syy = sums[:5]
        det = sxx * syy - sxy * sxy
        # The 2 x 2 solve in closed form: this runs at every terrain update of every filter.
        self.drift = float((syy * tx * tx - 2.0 * sxy * tx * ty + sxx * ty * ty) / det) if det > 0 else float("nan")
        return self.drift

    def shift_share(self) -> float:
        """The drift window's shifts against their expected spread: ``sum |d|^2 / sum trace(P_prior - P_post)``, about 1
        for a consistent filter, under it for a density wider than its error (NaN until the window is full)."""
        if self._n_corrections < len(self._corrections):
            return float("nan")
        window = self._corrections
        expected = float(np.sum(window[:, 2] + window[:, 4]))
        return float(np.sum(window[:, 0] ** 2 + window[:, 1] ** 2)) / expected if expected > 0 else float("nan")

    def _one_way(self, sums: np.ndarray) -> bool:
        """Whether the drift window's shifts say the density trails the truth (see ``TRAIL_SIGMAS``).

        The chi-square test above weighs the shifts by ``P_prior - P_post``, which the floor keeps large (the floor is
        process noise: under the filter's own model the truth may walk that far each update), and which a particle
        cloud measures with noise; a density trailing a lagging towfish by 0.7-1 m an update stays under its gate
        (``short``, seed 5: the PF became usable 18 m off with a 4.5 m sigma, the statistic at 3-5). Two things
        say it instead, per axis. The shifts of a consistent filter are independent and as likely one way as the
        other: a sign test sees their direction alone. And a filter of gain k per update that is pulled a mean d
        each update, by a prediction that drifts, lags by d / k in the steady state: that lag is measured in the
        density's own sigma (on that tow's PF 16.4 m measured for an error of 16.4 m, 3.8 sigma; afterwards under
        one sigma), so that a harmless consistent crawl (a velocity-bias filter a little behind a slowly changing
        error, the shifts one way for minutes but the lag within the density) keeps the flag.
        """
        n = len(self._corrections)
        if n < TRAIL_WINDOW_MIN:
            return False
        shifts = self._corrections[:, :2]
        positive, negative = (shifts > 0).sum(axis=0), (shifts < 0).sum(axis=0)
        one_way = np.maximum(positive, negative) >= ONE_WAY_SHARE * n
        lag = np.abs(sums[:2]) / np.maximum(sums[5:7], 1e-3 * n)  # the mean shift over the mean gain
        return bool(np.any(one_way & (lag > TRAIL_SIGMAS * np.sqrt(np.maximum(self._last_post_var, 0.0)))))

    def accepted(self, covariance: np.ndarray) -> None:
        """An update was used: reset growth and tempering, and advance the usable rule."""
        if self.returning:
            self.returning = False
            self.counts["returned_after_refusals"] += 1
        self.since_update_s = 0.0
        self.since_terrain_s = 0.0
        self._took_terrain = True
        self.travelled_m = 0.0
        self.outcomes.append(False)
        sigma = largest_sigma(covariance)
        drifting = self._p.drift_gate is not None and (self.drift > self._p.drift_gate or self.trailing)
        if drifting:
            self.counts["corrections_drifting"] += 1
            if self.trailing:
                self.counts["corrections_one_way"] += 1
        if sigma <= self._p.usable_sigma_nodes * self._node_m and not drifting:
            self.good_in_row += 1
        else:
            self.good_in_row = 0
        needed = self._p.usable_updates if self._p.matching == "patch" else self._p.usable_updates_point
        self.usable = self.good_in_row >= needed
        self.settled = self.settled or self.usable

    def watch(self, covariance: np.ndarray) -> None:
        """Between updates the flag drops as soon as the covariance outgrows the threshold."""
        sigma = largest_sigma(covariance)
        if sigma > self._p.usable_sigma_nodes * self._node_m:
            self.usable = False
            self.good_in_row = 0

    def sigma_max(self, covariance: np.ndarray) -> float:
        return largest_sigma(covariance)

    def look_alike(self, likelihood, mean: np.ndarray, covariance: np.ndarray, patch) -> bool:
        """The look-alike and wrong-place checks of an accepted patch update (see the module docstring).

        True when the filter should re-initialize: ``reinit_after`` of the last ``2 reinit_after`` checked
        patches fit better far from the estimate than near it.
        """
        sigma = self.sigma_max(covariance)
        if sigma > self._p.usable_sigma_nodes * self._node_m:
            return False
        if self.usable:
            self._usable_share = self.independent_share
        margin = likelihood.margin(mean, patch, radius_m=self._p.lookalike_radius_m, exclusion_m=max(3.0 * sigma, 2.0 * self._node_m))
        if not math.isfinite(margin):
            return False
        if margin < self._p.lookalike_margin:
            self.counts["lookalike"] += 1
            self.good_in_row = 0
            self.usable = False
        # The margin is a difference of two mean residuals over the patch: its noise goes as 1 / sqrt(N_eff), so the
        # wrong-place threshold grows by 1 / sqrt(independent share). On a smooth shelf under a survey map (share about
        # 0.1) a 0.5 margin elsewhere is the map's correlated error: shelf_canyon (seed 0) re-initialized twice on it
        # from the right place and locked 700 m off. A wrong lock measures its own mismatch as correlation, raising the
        # threshold that should undo it (offset seed 2003: share 0.68 -> 0.2), so the share when last usable counts too.
        better_elsewhere = margin < -self._p.elsewhere_margin / math.sqrt(max(self.independent_share, self._usable_share))
        self._elsewhere.append(better_elsewhere)
        if better_elsewhere:
            self.counts["fits_better_elsewhere"] += 1
        if sum(self._elsewhere) >= self._p.reinit_after:
            self._restart("reinitialized_elsewhere")
            return True
        return False

    def at_edge(self, on_map_mass: float, covariance: np.ndarray) -> bool:
        """Whether the density straddles the map's edge, where a patch is left out (see the module docstring).

        A narrow density with less than ``EDGE_MASS`` where the patch is wholly on the map; any density with less
        than half. The candidates off the map get the neutral (median) likelihood, so any on-map candidate
        that fits better than the median beats them: on ``seamount_ridges`` (seed 1) one patch at the map's edge
        took an 80 m wide density 75 m off, to 27 m wide, for 150 s.
        """
        narrow = self.sigma_max(covariance) <= 2.0 * self._p.usable_sigma_nodes * self._node_m
        return on_map_mass < (EDGE_MASS if narrow else WIDE_EDGE_MASS)

    def note_range_innovation(self, value: float) -> float:
        """A slant range's normalized innovation squared joins its gate's window; the gate's scale while usable
        (:class:`~lost.host.nav.gate.LearnedGate`).

        On ``seamount_ridges`` (seeds 2, 3, 8, 9) a 14 m outlier in a median NIS of 0.14 passed the stated gate and
        took both filters 10-16 m off while usable.
        """
        return self._range_gate.note(value)

    @property
    def range_scale(self) -> float:
        """The range gate's learned scale."""
        return self._range_gate.scale

    def note_fix_innovation(self, value: float) -> float:
        """A USBL fix's normalized innovation squared joins its gate's window; the gate's scale while usable.

        A fix's stated covariance is its device's figure; fixes off by three or four times it (multipath, refraction
        the processing's cast does not hold) passed the stated gate on ``usbl_nav`` (seed 1, the PF off its map:
        innovation NIS 12-13 where the fixes' median was 0.94) and took a narrow cloud 6-12 m off for a record.
        """
        return self._fix_gate.note(value)

    def range_outcome(self, refused: bool) -> bool:
        """A slant range was used or refused; several refused lower the usable flag. True: re-initialize now.

        Twice ``reinit_after`` ranges refused in a row, while the terrain updates are taken, say the
        terrain holds the density on a wrong place that every range contradicts (measured: the
        single-depth form locked 230 m off on ``demo`` and refused 286 ranges in a row).
        """
        self._ranges.append(refused)
        self._ranges_refused_in_row = self._ranges_refused_in_row + 1 if refused else 0
        if sum(self._ranges) >= 3:
            self.good_in_row = 0
            self.usable = False
        if self._ranges_refused_in_row >= 2 * self._p.reinit_after:
            self._restart("reinitialized_by_ranges")
            return True
        return False

    def _restart(self, reason: str | None) -> None:
        """A re-initialization: the evidence windows start afresh and the filter is no longer settled."""
        self.outcomes.clear()
        self._ranges.clear()
        self._ranges_refused_in_row = 0
        self._fixes_refused_in_row = 0
        self._elsewhere.clear()
        self._n_corrections = 0
        self.trailing = False
        self.settled = False
        self.returning = False
        self._took_terrain = False
        self.counts["reinitializations"] += 1
        if reason:
            self.counts[reason] += 1
        self.restart_cause = RESTART_CAUSES[reason]

    def rejected(self, reason: str) -> bool:
        """A terrain update was refused; True when the filter should re-initialize now (never on a return to the map)."""
        self.counts[f"rejected_{reason}"] += 1
        self.settled = False
        self.good_in_row = 0
        self.usable = False
        self.returning = self.returning or (self._took_terrain and self.since_terrain_s > self._p.off_map_usable_s)
        self.since_terrain_s = 0.0
        if self.returning:
            self.counts["refused_on_return"] += 1  # dead reckoning's density against the terrain: no lock to undo
            return False
        self.outcomes.append(True)
        if sum(self.outcomes) >= self._p.reinit_after:
            self._restart(None)
            return True
        return False
