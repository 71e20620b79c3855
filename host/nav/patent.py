"""The LOST patent's pipeline as an estimator of the record loop: state updater, MLE, CAT and SRC.

One record at a time, as in the patent's Figure 6 (US 09/599,868):

- State updater (eq. 1): the previous estimate moved by the measured velocity over the time step.
- MLE (eqs. 2-3): ``matching="patch"`` correlates the record's sonar patch against the sub-map of
  placements whose centre lies within ``search_half_width_m`` of the patch centre's prediction (the
  vehicle's plus the patch's ``centre_offset_m``), minimizes eq. 3 with V as the depth term and takes
  the offset off again; ``matching="point"`` matches the one ocean depth (vehicle depth + altitude)
  against every node of that area. Records without a measurement (no patch, a dropped altimeter)
  have no MLE; the estimate goes on by dead reckoning until the next one. So does a prediction that
  leaves the map (flagged ``off_map``). A search area that reaches past the map's edge is cut there
  and counted (``search_area_off_map``); a best fit on such a cut side may really lie beyond it, so it
  is not taken as a fix (``patch_edge_match``, ``point_edge_match``). A patch whose best placement in
  the area fits worse than ``misfit_gate`` times the residual that sonar noise and map error leave
  (``hypot(depth_noise_m, map_error_m)``) fits nowhere there: no fix (``patch_misfit``); where the
  area was cut by the map's edge, it was sounded beyond the map (``off_map``).
- CAT (eqs. 4-7) at each MLE, with dt the time since its previous update; along track the MLE.
- SRC (eq. 8) whenever a slant range is measured and passes the gate (ray-traced from the USBL's travel
  time when the record loop has a sound-speed profile).
- USBL fix (not in the patent): at a record without an MLE, once the last MLE is more than
  ``cat_restart_s`` old, a USBL fix that agrees with the prediction re-centres the dead reckoning,
  weighed against it (see ``_recentre``): the fixes carry the estimate through terrain gaps, and the
  terrain's MLE and CAT take over again at the next match. The SRC is not applied on top (the fix
  holds the same range). Without fixes in the records nothing changes.

The patent carries no covariance: the estimate's covariance is NaN, and it counts as usable while its
last MLE is at most ``cat_restart_s`` old.
"""

from __future__ import annotations

import math
from collections import Counter

import numpy as np

from ..records import SonarPatch
from .estimator import Estimate, Motion, Observation
from .likelihood import map_error_estimate
from .mapprep import PreparedMap
from .stages import patch_likelihood, point_likelihood, refine_minimum, slant_range_correct, state_update

__all__ = ["PatentEstimator"]


class _Matcher:
    """The MLE of one record against a prepared map, both forms."""

    def __init__(self, prepared: PreparedMap, params, counts: Counter) -> None:
        self._prep = prepared
        self._grid = prepared.grid
        self._params = params
        self._counts = counts
        self._half_nodes = int(math.ceil(params.search_half_width_m / self._grid.node_m))
        self.distinctness = float("nan")  # of the last patch match: runner-up V over best V
        self.clipped_edges = (False, False, False, False)
        self.misfit = float("nan")  # of the last patch: its best mean |residual| in the area over the expected
        self.beyond_map = False  # the last patch fit nowhere in an area the map's edge cut: sounded off the map
        map_error = params.map_error_m if params.map_error_m is not None else map_error_estimate(self._grid.depth_m)
        self._residual_sigma_m = math.hypot(params.depth_noise_m, map_error)

    def _window(self, centre_row: float, centre_col: float, rows: int, cols: int) -> tuple[int, int, int, int] | None:
        """Inclusive index ranges of the search area around a (fractional) node, clipped to [0, rows/cols).

        Sets ``clipped_edges`` to the sides (row 0, last row, column 0, last column) where the area
        reached past the map and was cut: a best fit on such a side may lie beyond it.
        """
        r, c = int(round(centre_row)), int(round(centre_col))
        self.clipped_edges = (r - self._half_nodes < 0, r + self._half_nodes > rows - 1, c - self._half_nodes < 0, c + self._half_nodes > cols - 1)
        r0, r1 = max(r - self._half_nodes, 0), min(r + self._half_nodes, rows - 1)
        c0, c1 = max(c - self._half_nodes, 0), min(c + self._half_nodes, cols - 1)
        if r0 > r1 or c0 > c1:
            return None
        if any(self.clipped_edges):
            self._counts["search_area_off_map"] += 1
        return r0, r1, c0, c1

    def _on_clipped_edge(self, i: int, j: int, rows: int, cols: int) -> bool:
        """Whether a best fit lies on a side of the search area that the map's edge cut off."""
        low_r, high_r, low_c, high_c = self.clipped_edges
        return (low_r and i == 0) or (high_r and i == rows - 1) or (low_c and j == 0) or (high_c and j == cols - 1)

    def patch(self, predicted: np.ndarray, sonar: SonarPatch) -> np.ndarray | None:
        self.distinctness = self.misfit = float("nan")
        self.beyond_map = False
        grid = self._grid
        if not math.isclose(sonar.node_m, grid.node_m, rel_tol=1e-9):
            raise ValueError(f"the sonar patch has {sonar.node_m} m nodes but the map {grid.node_m} m; grid the patch on the map's nodes")
        words, mask, dropped = self._prep.quantize_patch(sonar.depth_m)
        self._counts["patch_beams_out_of_word_range"] += dropped
        h, w = words.shape
        valid = int(mask.sum())
        if valid < self._params.min_valid_fraction * h * w:
            self._counts["patch_too_sparse"] += 1
            return None
        rows, cols = grid.shape
        if h > rows or w > cols:
            raise ValueError(f"the {h} x {w} sonar patch is larger than the {rows} x {cols} map")
        # The patch is matched where its centre is predicted; the vehicle is that far from it.
        offset = np.asarray(sonar.centre_offset_m, dtype=float)
        centre = predicted + offset
        row, col = grid.row_col(*centre)
        # Placement (i, j) puts the patch centre on node (i + (h-1)/2, j + (w-1)/2).
        area = self._window(row - (h - 1) / 2, col - (w - 1) / 2, rows - h + 1, cols - w + 1)
        if area is None:
            return None
        i0, i1, j0, j1 = area
        result = self._prep.correlation(words, mask, (i0, j0, i1 - i0 + 1, j1 - j0 + 1), backend=self._params.backend)
        surface = np.where(result.valid, result.surface, -1)
        if result.best is not None:
            # The best mean |residual| anywhere in the area, over what noise and map error leave at the true place.
            expected = self._residual_sigma_m / math.sqrt(2.0) * (valid - 1) / valid
            self.misfit = result.best.value * self._prep.lsb_m / valid**2 / max(expected, 1e-12)
            if self.misfit > self._params.misfit_gate:
                self._counts["patch_misfit"] += 1
                # Near the map's edge a patch that fits nowhere on the map was sounded beyond it.
                self.beyond_map = any(self.clipped_edges)
                return None
        x, y = grid.xy(np.arange(i0, i1 + 1)[:, None] + (h - 1) / 2, np.arange(j0, j1 + 1)[None, :] + (w - 1) / 2)
        value = patch_likelihood(centre[0] - x, centre[1] - y, surface, valid_nodes=valid, lsb_m=self._prep.lsb_m, k=self._params.k)
        if not np.isfinite(value).any():
            self._counts["patch_no_valid_placement"] += 1
            return None
        i, j = (int(x) for x in np.unravel_index(int(np.argmin(value)), value.shape))
        if self._on_clipped_edge(i0 + i, j0 + j, rows - h + 1, cols - w + 1):
            self._counts["patch_edge_match"] += 1
            return None
        radius = max(h, w) // 2
        others = np.where(surface < 0, np.iinfo(np.int64).max, surface)
        others[max(i - radius, 0) : i + radius + 1, max(j - radius, 0) : j + radius + 1] = np.iinfo(np.int64).max
        self.distinctness = float(others.min()) / max(int(surface[i, j]), 1) if others.size else float("inf")
        if self.distinctness < self._params.min_distinctness:
            self._counts["patch_ambiguous"] += 1
            return None
        fi, fj = refine_minimum(value, i, j)
        return np.array(grid.xy(i0 + fi + (h - 1) / 2, j0 + fj + (w - 1) / 2), dtype=float) - offset

    def point(self, predicted: np.ndarray, ocean_depth_m: float) -> np.ndarray | None:
        grid = self._grid
        rows, cols = grid.shape
        area = self._window(*grid.row_col(*predicted), rows, cols)
        if area is None:
            return None
        r0, r1, c0, c1 = area
        x, y = grid.xy(np.arange(r0, r1 + 1)[:, None], np.arange(c0, c1 + 1)[None, :])
        value = point_likelihood(predicted[0] - x, predicted[1] - y, ocean_depth_m, grid.depth_m[r0 : r1 + 1, c0 : c1 + 1], k=self._params.k)
        if not np.isfinite(value).any():
            self._counts["point_area_all_holes"] += 1
            return None
        r, c = (int(x) for x in np.unravel_index(int(np.argmin(value)), value.shape))
        if self._on_clipped_edge(r0 + r, c0 + c, rows, cols):
            self._counts["point_edge_match"] += 1
            return None
        return np.array(grid.xy(r0 + r, c0 + c), dtype=float)


class PatentEstimator:
    """The patent pipeline behind the estimator interface; its per-record stage outputs in ``Estimate.stages``.

    After each record they are: ``predicted``, ``mle`` (or None), ``distinctness``, ``cat`` (or
    None), ``cross_velocity_mps``, ``slant_corrected`` and ``off_map``.
    """

    name = "lost"

    def __init__(self, prepared: PreparedMap, params, counts: Counter) -> None:
        self._p = params
        self._grid = prepared.grid
        self.counts = counts
        self._matcher = _Matcher(prepared, params, counts)
        self._tracker = params.tracker()
        self._position = np.full(2, np.nan)
        self._last_update_t = float("nan")
        self._t = float("nan")
        self._dt = 0.0
        self._anchor_t, self._anchor_var, self._fixes_refused = float("nan"), float("nan"), 0
        self._stage = "uninitialized"
        self.last: dict = {}

    def start(self, t_s: float, position: np.ndarray, observation: Observation) -> None:
        self._position = np.asarray(position, float).copy()
        self._last_update_t = self._t = t_s
        # The last position the USBL gate trusts, and its variance per axis (the start: the lay-back's spread).
        self._anchor_t, self._anchor_var = t_s, self._p.initial_sigma_m**2
        self._fixes_refused = 0
        self._stage = "initialization"
        self.last = {"predicted": self._position.copy()}

    def predict(self, motion: Motion) -> None:
        self._position = state_update(self._position, motion.velocity_mps, motion.dt_s)
        self._dt = motion.dt_s
        self._t += motion.dt_s
        self.last = {"predicted": self._position.copy(), "mle": None, "distinctness": float("nan"), "cat": None,
                     "cross_velocity_mps": float("nan"), "slant_corrected": False, "off_map": False}

    def update(self, observation: Observation) -> None:
        p, counts, predicted = self._p, self.counts, self._position
        self._t = observation.t_s
        found: np.ndarray | None = None
        if not bool(self._grid.contains(*predicted)):
            self.last["off_map"] = True
            counts["off_map"] += 1
        elif p.matching == "patch":
            if observation.patch is not None:
                found = self._matcher.patch(predicted, observation.patch)
                self.last["distinctness"] = self._matcher.distinctness
                if found is None:
                    counts["patch_no_estimate"] += 1
                if self._matcher.beyond_map:
                    self.last["off_map"] = True
                    counts["off_map"] += 1
        elif np.isfinite(observation.ocean_depth_m):
            found = self._matcher.point(predicted, observation.ocean_depth_m)
        else:
            counts["point_no_depth"] += 1
        position = predicted
        frame = observation.frame
        if found is not None:
            self.last["mle"] = found
            if frame is None:
                counts["cat_no_ship_fix"] += 1
            else:
                since = observation.t_s - self._last_update_t
                if since > p.cat_restart_s:
                    self._tracker.restart()
                    counts["cat_restarts"] += 1
                    since = self._dt
                cross = self._tracker.update(predicted_cross_m=frame.cross(predicted), mle_cross_m=frame.cross(found), dt_s=since)
                position = self.last["cat"] = frame.position(frame.along(found), cross)
                self.last["cross_velocity_mps"] = self._tracker.velocity_mps
                self._last_update_t = observation.t_s
        if found is None and self._recentre(observation):
            self._stage = "usbl_fix"
            return
        self._position = self._slant_range(position, observation)
        self._stage = p.matching if found is not None else ("off_map" if self.last["off_map"] else "dead_reckoning")
        if found is not None:
            self._anchor_t, self._anchor_var, self._fixes_refused = observation.t_s, 0.0, 0

    def _recentre(self, observation: Observation) -> bool:
        """Re-centre the dead reckoning on a USBL fix when there has been no MLE for ``cat_restart_s``; True when done.

        The patent has no covariance. Here the dead reckoning gets a spread per axis: its last anchor's
        (``initial_sigma_m`` at the start, none at an MLE, what the last fix left) plus the velocity noise
        grown since and the position floor. The fix is gated against the prediction under that spread
        plus the fix's covariance (``gate_nis``: a late multipath reply is refused, a prediction that
        drifted in a long gap is not) and moves it by the weights of the two (a Kalman step: the first
        fix after the start is taken nearly whole, later ones are averaged with the dead reckoning
        between them). After ``reinit_after`` fixes refused in a row the prediction is taken for the
        wrong one (an earlier fix that passed was itself off) and the next fix is taken whole
        (``usbl_fix_forced``), as the filters re-initialize after refused updates.
        """
        p = self._p
        if not (p.use_usbl_fix and observation.fix_position_m is not None) or observation.t_s - self._last_update_t <= p.cat_restart_s:
            return False
        spread = (self._anchor_var + (p.velocity_noise_mps * (observation.t_s - self._anchor_t)) ** 2 + p.position_floor_m**2) * np.eye(2)
        fix, fix_cov = observation.fix_position_m, observation.fix_covariance_m2
        d = fix - self._position
        total = fix_cov + spread
        forced = float(d @ np.linalg.solve(total, d)) > p.gate_nis
        if forced and self._fixes_refused < p.reinit_after:
            self._fixes_refused += 1
            self.counts["usbl_fix_gated"] += 1
            return False
        self.counts["usbl_fix_forced" if forced else "usbl_fix_recentred"] += 1
        self._fixes_refused = 0
        if forced:
            self._position, left = fix.copy(), fix_cov
        else:
            gain = spread @ np.linalg.inv(total)
            self._position, left = self._position + gain @ d, (np.eye(2) - gain) @ spread
        self._anchor_t, self._anchor_var = observation.t_s, float(np.trace(left)) / 2.0
        return True

    def _slant_range(self, position: np.ndarray, observation: Observation) -> np.ndarray:
        """Slant-range corrector on the horizontal range left by the known depth difference."""
        p, frame, slant, depth = self._p, observation.frame, observation.slant_range_m, observation.vehicle_depth_m
        if not (p.use_slant_range and np.isfinite(slant) and frame is not None and np.isfinite(depth)):
            return position
        horizontal_sq = slant**2 - (depth - p.reference_depth_m) ** 2
        ship = np.array([frame.ship_x_m, frame.ship_y_m])
        if horizontal_sq <= 0:
            self.counts["slant_range_shorter_than_depth"] += 1
            return position
        if abs(math.sqrt(horizontal_sq) - float(np.linalg.norm(position - ship))) > p.slant_range_gate_m:
            self.counts["slant_range_gated"] += 1
            return position
        self.last["slant_corrected"] = True
        return slant_range_correct(position, ship, math.sqrt(horizontal_sq))

    def estimate(self) -> Estimate:
        usable = self._t - self._last_update_t <= self._p.cat_restart_s and self._stage != "initialization"
        return Estimate(position=self._position.copy(), covariance=np.full((2, 2), np.nan), usable=bool(usable), stage=self._stage,
                        stages=dict(self.last))
