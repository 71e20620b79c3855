"""The LOST pipeline driver: state updater -> MLE -> constrained adaptive tracker -> slant-range corrector.

One record at a time, as in the patent's Figure 6, over a :class:`~lost.host.records.NavRecords`
and a :class:`~lost.host.grid.Grid`. Two baselines run on the same records: the lay-back model and
dead reckoning from the same start.

What happens at a record
------------------------
- State updater (eq. 1): the previous estimate moved by the measured velocity over the time step; a
  missing velocity is replaced by the last one measured (counted).
- MLE (eqs. 2-3): ``matching="patch"`` correlates the record's sonar patch against the sub-map of
  placements whose centre lies within ``search_half_width_m`` of the patch centre's prediction (the
  vehicle's plus the patch's ``centre_offset_m``; the correlator backend is a parameter), minimizes
  eq. 3 with V as the depth term and takes the offset off again; ``matching="point"``
  matches the one ocean depth (vehicle depth + altitude) against every node of that area. Records
  without a measurement (no patch, a dropped altimeter) have no MLE; the estimate goes on by dead
  reckoning until the next one. So does a prediction whose search area leaves the map: the record
  is flagged ``off_map`` and counted.
- CAT (eqs. 4-7) at each MLE, with dt the time since its previous update; along track the MLE.
- SRC (eq. 8) whenever a slant range is measured and passes the gate.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field

import numpy as np

from ..correlator import BACKENDS, correlate
from ..grid import Grid
from ..records import NavRecords, SonarPatch
from .mapprep import PreparedMap
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

__all__ = ["NavParameters", "NavResult", "run_lost", "layback_distance"]

MATCHING = ("patch", "point")
LAYBACK_MODELS = ("cable", "depth_ratio")


@dataclass(frozen=True, kw_only=True)
class NavParameters:
    """Every constant of the pipeline, with the patent's nominal value where it gives one.

    Attributes
    ----------
    matching : {"patch", "point"}
        MLE form: the correlator surface of a sonar patch, or the patent's single ocean depth.
    k : float
        The patent's k = sigma_x / sigma_z of eqs. 2-3 (nominal 100-1000; larger for rough terrain,
        smaller when the data are suspect); the depth term is weighted by k**2 (see
        ``point_likelihood``). Default 100, the low end: on the shipped scenarios 300 and 1000 let
        single ambiguous matches on smooth terrain pull the estimate (measured, see the README).
    u : float
        CAT adaptive constant (patent nominal 0.001-0.01). Default 0.01.
    max_cross_accel_mps2, max_cross_speed_mps : float
        Thresholds of f_a and f_v in eqs. 5-6, from the vehicle's dynamics (the patent gives no
        number): 0.05 m/s**2 and 1.0 m/s, about a tow body's turn response at 2-4 kn.
    cat_restart_s : float
        When the tracker's previous update is older than this (no usable MLE for that long: no patch,
        ambiguous matches, off the map), it restarts: w = 0 and Δt the last record step. Eq. 7
        moves the estimate by w Δt on top of a one-record prediction, so a stale w over a long gap
        would throw it hundreds of metres (seen in a turn). Not in the patent, whose MLE runs at
        every update. Default 30 s.
    cross_damping_per_s : float or None
        Decay rate of the CAT's cross-track velocity w, 1/s, in place of eq. 6's ``(1 - u)`` per
        update: a documented departure from the patent, whose tracker rings (damping ratio 0.035 at
        u = 0.01; see :class:`~lost.host.nav.stages.CrossTrackTracker`). Default None, the patent's;
        the shipped scenarios use 0.05.
    search_half_width_m : float
        Half side of the square MLE search area centred on the prediction (the patent leaves the
        size to the convergence/cost trade-off). Default 300 m, enough for a 200 m start error.
    min_valid_fraction : float
        A patch with fewer valid beams than this fraction of its nodes is skipped (counted).
    min_distinctness : float
        A patch match is used only if the smallest V farther than half a patch (Chebyshev) from the
        chosen placement is at least this many times the chosen placement's V (Nygren's secondary
        peaks); otherwise the record dead-reckons (counted as ``patch_ambiguous``). The default 1
        rejects only a match where a distant placement fits the patch better than the chosen one,
        i.e. the distance prior outweighed the terrain; 0 disables the test. Higher values skip
        more matches where the floor turns smooth (measured on ``two_hour``, see the README: 1.2
        changes the RMS by a few tenths of a metre either way). Not in the patent.
    use_slant_range : bool
        Apply the SRC when a slant range is measured.
    slant_range_gate_m : float
        An SRC correction longer than this is taken for an outlier range and skipped (counted).
    reference_depth_m : float
        Depth of the range's reference point (the ship's transducer), metres.
    layback_model : {"cable", "depth_ratio"}
        Initialization and baseline: the horizontal lay-back is ``sqrt(cable_out**2 - depth**2)``
        (the cable taken as straight, the patent's "cable paid out is the slant range"), or
        ``layback_depth_ratio * depth`` (the patent's "fixed multiple of the depth").
    layback_depth_ratio : float
        Lay-back per metre of vehicle depth for ``"depth_ratio"``.
    initial_offset_m : (float, float)
        Added to the lay-back initialization (east, north): to study convergence from a known error.
    lsb_m : float or None
        Depth word step for the correlator; None chooses one from the map (see PreparedMap).
    backend : str
        Correlator backend name (``lost.host.BACKENDS``).
    """

    matching: str = "patch"
    k: float = 100.0
    u: float = 0.01
    max_cross_accel_mps2: float = 0.05
    max_cross_speed_mps: float = 1.0
    cross_damping_per_s: float | None = None
    cat_restart_s: float = 30.0
    search_half_width_m: float = 300.0
    min_valid_fraction: float = 0.5
    min_distinctness: float = 1.0
    use_slant_range: bool = True
    slant_range_gate_m: float = 15.0
    reference_depth_m: float = 0.0
    layback_model: str = "cable"
    layback_depth_ratio: float = 1.5
    initial_offset_m: tuple[float, float] = (0.0, 0.0)
    lsb_m: float | None = None
    backend: str = "software"

    def __post_init__(self) -> None:
        if self.matching not in MATCHING:
            raise ValueError(f"matching must be one of {MATCHING}, got {self.matching!r}.")
        if self.layback_model not in LAYBACK_MODELS:
            raise ValueError(f"layback_model must be one of {LAYBACK_MODELS}, got {self.layback_model!r}.")
        if self.backend not in BACKENDS:
            raise ValueError(f"backend must be one of {sorted(BACKENDS)}, got {self.backend!r}.")
        for name in ("k", "search_half_width_m", "slant_range_gate_m", "layback_depth_ratio", "cat_restart_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite number, got {value!r}.")
        if not (math.isfinite(self.min_distinctness) and self.min_distinctness >= 0.0):
            raise ValueError(f"min_distinctness must be a finite number, at least 0 (0 disables the test), got {self.min_distinctness!r}.")
        if not 0.0 < self.min_valid_fraction <= 1.0:
            raise ValueError(f"min_valid_fraction must lie in (0, 1], got {self.min_valid_fraction!r}.")
        if len(self.initial_offset_m) != 2 or not all(math.isfinite(float(x)) for x in self.initial_offset_m):
            raise ValueError(f"initial_offset_m must be two finite numbers (east, north), got {self.initial_offset_m!r}.")
        object.__setattr__(self, "initial_offset_m", tuple(float(x) for x in self.initial_offset_m))
        # The tracker validates u, its thresholds and damping with its own messages.
        self.tracker()

    def tracker(self) -> CrossTrackTracker:
        """A fresh constrained adaptive tracker with these settings."""
        return CrossTrackTracker(u=self.u, max_accel_mps2=self.max_cross_accel_mps2, max_speed_mps=self.max_cross_speed_mps,
                                 damping_per_s=self.cross_damping_per_s)

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class NavResult:
    """Per-record outputs of every stage and the baselines; positions are (N, 2) arrays (east, north).

    ``mle_source`` is ``"patch"``, ``"point"`` or ``""`` (no MLE at that record); ``distinctness``
    the runner-up-to-best V ratio of each patch match (NaN without one); NaN rows mean the
    stage had no output. ``counts`` names every skip and substitution the run made.
    """

    t_s: np.ndarray
    estimate: np.ndarray
    predicted: np.ndarray
    mle: np.ndarray
    mle_source: np.ndarray
    distinctness: np.ndarray
    cat: np.ndarray
    cross_velocity_mps: np.ndarray
    slant_corrected: np.ndarray
    off_map: np.ndarray
    layback: np.ndarray
    dead_reckoning: np.ndarray
    truth: np.ndarray | None
    counts: dict[str, int] = field(default_factory=dict)


def layback_distance(cable_out_m: float, vehicle_depth_m: float, params: NavParameters) -> float:
    """Horizontal ship-to-vehicle distance of the lay-back model (NaN when its input is missing)."""
    if params.layback_model == "depth_ratio":
        return params.layback_depth_ratio * vehicle_depth_m
    return math.sqrt(max(cable_out_m**2 - vehicle_depth_m**2, 0.0))


class _Matcher:
    """The MLE of one record against a prepared map, both forms."""

    def __init__(self, prepared: PreparedMap, params: NavParameters, counts: Counter) -> None:
        self._prep = prepared
        self._grid = prepared.grid
        self._params = params
        self._counts = counts
        self._half_nodes = int(math.ceil(params.search_half_width_m / self._grid.node_m))
        self.distinctness = float("nan")  # of the last patch match: runner-up V over best V

    def _window(self, centre_row: float, centre_col: float, rows: int, cols: int) -> tuple[int, int, int, int] | None:
        """Inclusive index ranges of the search area around a (fractional) node, clipped to [0, rows/cols)."""
        r, c = int(round(centre_row)), int(round(centre_col))
        r0, r1 = max(r - self._half_nodes, 0), min(r + self._half_nodes, rows - 1)
        c0, c1 = max(c - self._half_nodes, 0), min(c + self._half_nodes, cols - 1)
        if r0 > r1 or c0 > c1:
            return None
        return r0, r1, c0, c1

    def patch(self, predicted: np.ndarray, sonar: SonarPatch) -> np.ndarray | None:
        self.distinctness = float("nan")
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
        surface = correlate(self._prep.words[i0 : i1 + h, j0 : j1 + w], words, mask=mask, backend=self._params.backend)
        surface = np.where(self._prep.placements_touching_holes((h, w))[i0 : i1 + 1, j0 : j1 + 1], -1, surface)
        x, y = grid.xy(np.arange(i0, i1 + 1)[:, None] + (h - 1) / 2, np.arange(j0, j1 + 1)[None, :] + (w - 1) / 2)
        value = patch_likelihood(centre[0] - x, centre[1] - y, surface, valid_nodes=valid, lsb_m=self._prep.lsb_m, k=self._params.k)
        if not np.isfinite(value).any():
            self._counts["patch_no_valid_placement"] += 1
            return None
        i, j = (int(x) for x in np.unravel_index(int(np.argmin(value)), value.shape))
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
        r, c = np.unravel_index(int(np.argmin(value)), value.shape)
        return np.array(grid.xy(r0 + r, c0 + c), dtype=float)


def _frame(records: NavRecords, n: int) -> TrackFrame | None:
    x, y, h = records.ship_x_m[n], records.ship_y_m[n], records.ship_heading_deg[n]
    if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(h)):
        return None
    return TrackFrame(float(x), float(y), float(h))


def run_lost(
    records: NavRecords,
    grid: Grid,
    params: NavParameters | None = None,
    *,
    prepared: PreparedMap | None = None,
    progress: Callable[[Iterable[int]], Iterable[int]] | None = None,
) -> NavResult:
    """Run the LOST pipeline and both baselines over a tow.

    Parameters
    ----------
    records : NavRecords
        The tow's sensor records.
    grid : Grid
        The bathymetry, in the records' frame.
    params : NavParameters
        Constants; the defaults are the patent's nominal values where it gives them.
    prepared : PreparedMap, optional
        The grid already quantized (to reuse across runs); built from ``grid`` otherwise.
    progress : callable, optional
        Wraps the record loop's iterable (e.g. ``rich.progress.track``).

    Raises
    ------
    ValueError
        Patch matching on a tow without sonar patches, a sonar patch on other nodes than the map, a
        prepared map of another grid.
    """
    return _run(records, grid, params, prepared, progress)


def _run(
    records: NavRecords,
    grid: Grid,
    params: NavParameters | None,
    prepared: PreparedMap | None,
    progress: Callable[[Iterable[int]], Iterable[int]] | None,
) -> NavResult:
    params = params or NavParameters()
    prepared = prepared or PreparedMap(grid=grid, lsb_m=params.lsb_m)
    if prepared.grid is not grid:
        raise ValueError("the prepared map was made from another grid than the one given")
    if params.matching == "patch" and not any(patch is not None for patch in records.sonar):
        raise ValueError("the tow has no sonar patch, so patch matching has nothing to match; use matching='point'")
    n_records = len(records)
    counts: Counter = Counter()
    estimate, predicted, mle, cat, layback, dead = (np.full((n_records, 2), np.nan) for _ in range(6))
    mle_source = np.full(n_records, "", dtype="<U5")
    cross_velocity = np.full(n_records, np.nan)
    distinctness = np.full(n_records, np.nan)
    slant_corrected = np.zeros(n_records, dtype=bool)
    off_map = np.zeros(n_records, dtype=bool)
    matcher = _Matcher(prepared, params, counts)
    tracker = params.tracker()
    sonar = records.sonar if records.sonar else (None,) * n_records

    velocity = np.zeros(2)
    last_depth = float("nan")
    previous: np.ndarray | None = None
    dead_previous: np.ndarray | None = None
    last_update_t = float("nan")
    iterator: Iterable[int] = range(n_records)
    if progress is not None:
        iterator = progress(iterator)
    for n in iterator:
        t = float(records.t_s[n])
        frame = _frame(records, n)
        measured_velocity = np.array([records.vel_x_mps[n], records.vel_y_mps[n]])
        if np.all(np.isfinite(measured_velocity)):
            velocity = measured_velocity
        elif previous is not None:
            counts["velocity_held"] += 1
        depth = float(records.vehicle_depth_m[n])
        if np.isfinite(depth):
            last_depth = depth
        distance = layback_distance(float(records.cable_out_m[n]), last_depth, params)
        if frame is not None and np.isfinite(distance):
            layback[n] = layback_position(frame, distance)

        if previous is None:
            # Initialization: the lay-back model (cross-track zero), plus the requested offset.
            if not np.all(np.isfinite(layback[n])):
                counts["before_initialization"] += 1
                continue
            previous = layback[n] + np.array(params.initial_offset_m)
            dead_previous = previous.copy()
            estimate[n] = predicted[n] = dead[n] = previous
            last_update_t = t
            continue

        dt = t - float(records.t_s[n - 1])
        predicted[n] = state_update(previous, velocity, dt)
        dead[n] = dead_previous = state_update(dead_previous, velocity, dt)

        # Maximum-likelihood estimator, patch or point form.
        found: np.ndarray | None = None
        if not bool(grid.contains(*predicted[n])):
            off_map[n] = True
            counts["off_map"] += 1
        elif params.matching == "patch":
            if sonar[n] is not None:
                found = matcher.patch(predicted[n], sonar[n])
                distinctness[n] = matcher.distinctness
                if found is None:
                    counts["patch_no_estimate"] += 1
        else:
            ocean_depth = depth + float(records.altitude_m[n])
            if np.isfinite(ocean_depth):
                found = matcher.point(predicted[n], ocean_depth)
            else:
                counts["point_no_depth"] += 1

        # Constrained adaptive tracker: along track from the MLE, cross track through eqs. 4-7.
        position = predicted[n]
        if found is not None:
            mle[n] = found
            mle_source[n] = params.matching
            if frame is None:
                counts["cat_no_ship_fix"] += 1
            else:
                since = t - last_update_t
                if since > params.cat_restart_s:
                    tracker.restart()
                    counts["cat_restarts"] += 1
                    since = dt
                cross = tracker.update(predicted_cross_m=frame.cross(predicted[n]), mle_cross_m=frame.cross(found), dt_s=since)
                position = cat[n] = frame.position(frame.along(found), cross)
                cross_velocity[n] = tracker.velocity_mps
                last_update_t = t

        # Slant-range corrector on the horizontal range left by the known depth difference.
        slant = float(records.slant_range_m[n])
        if params.use_slant_range and np.isfinite(slant) and frame is not None and np.isfinite(last_depth):
            horizontal_sq = slant**2 - (last_depth - params.reference_depth_m) ** 2
            ship = np.array([frame.ship_x_m, frame.ship_y_m])
            if horizontal_sq <= 0:
                counts["slant_range_shorter_than_depth"] += 1
            elif abs(math.sqrt(horizontal_sq) - float(np.linalg.norm(position - ship))) > params.slant_range_gate_m:
                counts["slant_range_gated"] += 1
            else:
                position = slant_range_correct(position, ship, math.sqrt(horizontal_sq))
                slant_corrected[n] = True
        estimate[n] = previous = position

    truth = None
    if records.has_truth:
        truth = np.column_stack([records.truth_x_m, records.truth_y_m])
    counts["records"] = n_records
    counts["mle_updates"] = int(np.count_nonzero(mle_source != ""))
    counts["slant_range_corrections"] = int(slant_corrected.sum())
    return NavResult(
        t_s=np.asarray(records.t_s, float),
        estimate=estimate,
        predicted=predicted,
        mle=mle,
        mle_source=mle_source,
        distinctness=distinctness,
        cat=cat,
        cross_velocity_mps=cross_velocity,
        slant_corrected=slant_corrected,
        off_map=off_map,
        layback=layback,
        dead_reckoning=dead,
        truth=truth,
        counts=dict(counts),
    )
