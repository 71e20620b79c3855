"""The record loop: every record through each estimator, with the lay-back and dead-reckoning baselines.

One record at a time over a :class:`~lost.host.records.NavRecords` and a :class:`~lost.host.grid.Grid`:
the loop turns the record into a :class:`~lost.host.nav.estimator.Motion` (the measured velocity, the
last one held when a reading is missing, counted) and an :class:`~lost.host.nav.estimator.Observation`
(patch, ocean depth, slant range, ship fix), and hands both to each estimator in turn: the LOST
patent pipeline (:mod:`lost.host.nav.patent`), the point-mass filter (:mod:`lost.host.nav.pmf`) and
the particle filter (:mod:`lost.host.nav.pf`). All start from the lay-back model's position (plus
``initial_offset_m``) at the first record that has one. Two baselines run on the same records: the
lay-back model and dead reckoning from the same start.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..correlator import BACKENDS
from ..grid import Grid
from ..records import NavRecords
from .estimator import Estimator, Motion, Observation
from .likelihood import LIKELIHOODS, TerrainLikelihood, map_error_estimate
from .mapprep import PreparedMap
from .patent import PatentEstimator
from .pf import ParticleFilter
from .pmf import PointMassFilter
from .stages import CrossTrackTracker, TrackFrame, layback_position, state_update

if TYPE_CHECKING:
    from ..usbl.sound import SoundSpeedProfile

__all__ = ["NavParameters", "NavResult", "FilterTrack", "ESTIMATORS", "navigate", "run_lost", "layback_distance"]

#: The estimators of ``navigate`` (``lost run --estimator``).
ESTIMATORS = ("lost", "pmf", "pf")

MATCHING = ("patch", "point")
LAYBACK_MODELS = ("cable", "depth_ratio")


@dataclass(frozen=True, kw_only=True)
class NavParameters:
    """Every constant of the navigation, with the patent's nominal value where it gives one.

    The patent pipeline
    -------------------
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

    The Bayesian filters (point-mass and particle; see ``lost.host.nav.trust`` for the rules)
    --------------------------------------------------------------------------------------------
    depth_noise_m : float
        1-sigma error of a sonar patch node (binned soundings), metres. Default 0.5.
    map_error_m : float or None
        1-sigma error of the map where a patch node samples it (survey noise and interpolation
        between nodes). None: estimated from the map (``likelihood.map_error_estimate``). The residual
        sigma of the likelihood is ``hypot(depth_noise_m, map_error_m)``.
    likelihood : {"laplace", "gaussian"}
        The residual distribution: Laplace uses the correlator's sum of absolute differences as the
        hardware gives it; Gaussian is eq. 3.4 (a sum of squares on the host).
    likelihood_weight : float
        Multiplies every terrain log-likelihood (after the new-share tempering). Default 1.
    initial_sigma_m : float
        1-sigma of the start position about the lay-back model, each axis; also the width a
        re-initialization widens to. Default 300 m.
    velocity_noise_mps : float
        1-sigma white error of each velocity reading, m/s (the motion's uncertainty, eq. 3.1's v_t).
    gyro_bias_rps, accel_bias_mps2 : float
        RMS gyro and accelerometer biases of the INS error model (eq. 6.2) that widens the density
        while no update arrives. Defaults 0.01 deg/h and 10 micro-g, a navigation-grade INS.
    estimate_velocity_bias : bool
        Whether the point-mass filter estimates its velocity bias (a Kalman filter on the drift of its
        corrections, :mod:`lost.host.nav.velocity_bias`). Default True.
    bias_learning_updates : int
        Terrain updates in a row with the density under the usable width before the point-mass filter
        learns its velocity bias from its corrections (before, they are the acquisition's own moves).
        Default 5. Once usable (30) was too late on ``short``, whose towfish lags the ship it is
        reckoned by (0.1-0.2 m/s): its patches were misplaced by up to 8 m through the first minute
        (RMS 2.70 m; 2.20 m with 5; 2.35 with 10). 3: ``short``'s NEES in band 0.90, under its 0.92.
    velocity_bias_sigma_mps, velocity_bias_walk_mps : float
        The prior on the velocity bias (1-sigma, m/s) and its random walk (m/s per square-root second),
        for both filters: the particles' bias state and the point-mass filter's bias filter.
    depth_bias_sigma_m, depth_bias_walk_m : float
        The single-depth (point) form's depth bias, measured ocean depth minus the map (tide, a
        pressure-depth error, a datum): its prior 1-sigma, metres, and its random walk, metres per
        square-root second. Defaults 3 m and 0.002 (0.2 m in three hours). The patch form needs no
        such state: mean compensation removes a constant bias.
    slant_range_sigma_m : float
        1-sigma of a slant range for the filters, which take it as a measurement (gated), not as the
        patent's correction.
    position_floor_nodes, position_floor_m : float
        The density is kept at least ``hypot(position_floor_nodes * node, position_floor_m)`` wide
        (1-sigma, each axis): the map says nothing of the terrain between its nodes, and a real-time
        patch's own position is reckoned over its age, so the errors of successive matches are not
        independent and no number of them places the vehicle better than a fraction of a node and
        the patch's registration error. Without the floor the density collapses into a cell and can
        no longer follow the slowly varying error of the matches (measured: NEES far above its
        band). Defaults 0.1 node and 2.3 m (fitted on ``demo`` and ``coarse_map``: 2.5 m at 10 m
        nodes, 5.5 m at 50 m). This floor holds while the filter acquires; once it is usable,
        ``position_floor_tracking_m`` takes the place of ``position_floor_m``.
    position_floor_tracking_m, pf_floor_tracking_m : float
        The metres part of the floor once the filter is settled, for the point-mass and the particle
        filter. Defaults 0.8 and 0.9 (1.3 and 1.35 m at 10 m nodes). The point-mass filter at 1.0 was
        wider than its error: NEES in band 0.90 on ``two_hour``, 0.88 on ``offset`` (0.91 and 0.89 at
        0.8). The particle filter at 0.8 lost accuracy on five shipped scenarios of seven (``map_short``
        1.35 -> 2.45 m: a narrower cloud keeps fewer distinct particles), at 1.0 it was wider than its
        error on ``usbl_nav`` (NEES in band 0.88; 0.91 at 0.9).
    pmf_cells : int
        Most cells a side of the point-mass grid. Default 96.
    pmf_sigmas : float
        The grid's half-width in standard deviations of the density. Default 4.
    pmf_min_cell_m : float or None
        Smallest cell, metres; None: a tenth of a map node.
    pf_particles : int
        Particles of the particle filter. Default 10,000.
    gate_nis : float
        A terrain or range update whose NIS exceeds this is refused. Default 13.8 (chi-square, 2
        degrees of freedom, 0.999).
    misfit_gate : float
        A patch whose best mean absolute residual in the filter's area exceeds this many times the
        running residual level fits nowhere there: refused. Default 2.2 (measured on the shipped
        floors: about 1 +- 0.4 at the true position, 2.5 to 10 at a wrong one).
    usable_sigma_nodes, usable_updates : float, int
        The usable flag: the covariance's largest 1-sigma axis under this many map nodes for this many
        terrain updates in a row. Defaults 1 node, 30 updates (20 let the early minute of ``short``,
        still some 10 m off, count as usable: measured).
    usable_updates_point : int
        ``usable_updates`` for the single-depth form, whose updates each carry one depth where a patch
        carries a hundred: default 200, MB-System's figure (30 let the point form on ``demo`` claim
        fixes 235 m off: measured, 130 false fixes; 200: none).
    lookalike_radius_m, lookalike_margin : float
        The look-alike check of a usable filter's patches: how far around the estimate a second fit
        is looked for (default 600 m), and how much worse it must fit, in mean absolute residual
        over sigma per node, for the estimate to stay usable (default 0.15; measured at the true
        position on the shipped floors: at least 0.39 better than anywhere else, about 0 on
        ``lookalike``).
    elsewhere_margin : float
        The wrong-place check, on the look-alike check's patches: a placement beyond three sigma that fits
        better than the best near the estimate by more than this (same units) says the density sits on
        the wrong place; ``reinit_after`` such patches among the last ``2 reinit_after`` re-initialize the
        filter (counted ``reinitialized_elsewhere``). Default 0.5 (measured on ``offset`` over six terrain
        seeds: -1 to -3 on a wrong lock, never below 0 at the true place).
    reinit_after : int
        Terrain updates refused in a row before the filter re-initializes. Default 10.
    seed : int
        The particle filter's random stream.

    The USBL (records with ``usbl_*`` series; see ``navigate``'s ``profile`` for the ray-traced range)
    --------------------------------------------------------------------------------------------------
    use_usbl_fix : bool
        Use the records' USBL fixes: the Bayesian filters as a Gaussian position measurement with the
        fix's covariance (gated by ``gate_nis``, counted ``fix_updates``, ``fix_rejected_gate``; the
        record's slant range is then not used again, ``range_in_fix``); the patent pipeline to
        re-centre its dead reckoning when it has had no MLE for ``cat_restart_s``. Default True.
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
    depth_noise_m: float = 0.5
    map_error_m: float | None = None
    likelihood: str = "laplace"
    likelihood_weight: float = 1.0
    initial_sigma_m: float = 300.0
    velocity_noise_mps: float = 0.05
    gyro_bias_rps: float = math.radians(0.01) / 3600.0
    accel_bias_mps2: float = 10e-6 * 9.81
    estimate_velocity_bias: bool = True
    bias_learning_updates: int = 5
    velocity_bias_sigma_mps: float = 0.05
    velocity_bias_walk_mps: float = 0.0005
    depth_bias_sigma_m: float = 3.0
    depth_bias_walk_m: float = 0.002
    slant_range_sigma_m: float = 3.0
    position_floor_nodes: float = 0.1
    position_floor_m: float = 2.3
    position_floor_tracking_m: float = 0.8
    pf_floor_tracking_m: float = 0.9
    pmf_cells: int = 96
    pmf_sigmas: float = 4.0
    pmf_min_cell_m: float | None = None
    pf_particles: int = 10_000
    gate_nis: float = 13.8
    misfit_gate: float = 2.2
    usable_sigma_nodes: float = 1.0
    usable_updates: int = 30
    usable_updates_point: int = 200
    lookalike_radius_m: float = 600.0
    lookalike_margin: float = 0.15
    elsewhere_margin: float = 0.5
    reinit_after: int = 10
    seed: int = 0
    use_usbl_fix: bool = True

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
        if self.likelihood not in LIKELIHOODS:
            raise ValueError(f"likelihood must be one of {LIKELIHOODS}, got {self.likelihood!r}.")
        for name in ("depth_noise_m", "likelihood_weight", "initial_sigma_m", "slant_range_sigma_m", "pmf_sigmas", "gate_nis",
                     "misfit_gate", "usable_sigma_nodes", "lookalike_radius_m", "elsewhere_margin"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite number, got {value!r}.")
        for name in ("position_floor_nodes", "position_floor_m", "position_floor_tracking_m", "pf_floor_tracking_m", "velocity_noise_mps",
                     "gyro_bias_rps", "accel_bias_mps2", "velocity_bias_sigma_mps", "velocity_bias_walk_mps", "depth_bias_sigma_m", "depth_bias_walk_m"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number, at least 0, got {value!r}.")
        for name in ("map_error_m", "pmf_min_cell_m"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite number or None, got {value!r}.")
        for name, low in (("pmf_cells", 8), ("pf_particles", 10), ("usable_updates", 1), ("usable_updates_point", 1),
                          ("reinit_after", 1), ("bias_learning_updates", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"{name} must be a whole number of at least {low}, got {value!r}.")
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
class FilterTrack:
    """One estimator's outputs at every record (NaN rows before it starts).

    Attributes
    ----------
    position : (N, 2) array
    covariance : (N, 2, 2) array, m**2 (NaN for an estimator that carries none)
    usable : (N,) bool array
    stage : (N,) str array, one of ``lost.host.nav.estimator.STAGES``
    nis : (N,) array, the terrain update's NIS (NaN without one)
    rejected : (N,) str array, why a measurement was refused ("" when none was)
    ms : (N,) array, wall time of the estimator's predict + update at each record, milliseconds
    depth_bias_m : (N,) array, the single-depth form's depth-bias estimate (NaN for the patch form)
    velocity_bias_mps, velocity_bias_sigma_mps : (N, 2) arrays, the velocity-bias estimate and its 1-sigma
        (east, north), m/s (NaN where the estimator has none)
    counts : dict, every skip, rejection and re-initialization the estimator made
    """

    position: np.ndarray
    covariance: np.ndarray
    usable: np.ndarray
    stage: np.ndarray
    nis: np.ndarray
    rejected: np.ndarray
    ms: np.ndarray
    depth_bias_m: np.ndarray
    velocity_bias_mps: np.ndarray
    velocity_bias_sigma_mps: np.ndarray
    counts: dict[str, int] = field(default_factory=dict)

    @classmethod
    def empty(cls, n: int) -> FilterTrack:
        return cls(np.full((n, 2), np.nan), np.full((n, 2, 2), np.nan), np.zeros(n, bool), np.full(n, "uninitialized", dtype="<U14"),
                   np.full(n, np.nan), np.full(n, "", dtype="<U32"), np.full(n, np.nan), np.full(n, np.nan), np.full((n, 2), np.nan),
                   np.full((n, 2), np.nan))


@dataclass(frozen=True)
class NavResult:
    """Per-record outputs of every estimator and the baselines; positions are (N, 2) arrays (east, north).

    The patent pipeline's stage outputs have fields of their own (``estimate`` is its answer);
    ``mle_source`` is ``"patch"``, ``"point"`` or ``""`` (no MLE at that record); ``distinctness``
    the runner-up-to-best V ratio of each patch match (NaN without one); NaN rows mean the
    stage had no output. ``counts`` names every skip and substitution the record loop and the patent
    pipeline made. ``tracks`` holds every estimator's :class:`FilterTrack` by name (``"lost"``,
    ``"pmf"``, ``"pf"``), those that ran.
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
    tracks: dict[str, FilterTrack] = field(default_factory=dict)


def layback_distance(cable_out_m: float, vehicle_depth_m: float, params: NavParameters) -> float:
    """Horizontal ship-to-vehicle distance of the lay-back model (NaN when its input is missing)."""
    if params.layback_model == "depth_ratio":
        return params.layback_depth_ratio * vehicle_depth_m
    return math.sqrt(max(cable_out_m**2 - vehicle_depth_m**2, 0.0))


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
    profile: SoundSpeedProfile | None = None,
) -> NavResult:
    """The LOST patent pipeline alone (and both baselines) over a tow: ``navigate(..., estimators=("lost",))``."""
    return navigate(records, grid, params, estimators=("lost",), prepared=prepared, progress=progress, profile=profile)


def make_estimators(names: Iterable[str], prepared: PreparedMap, params: NavParameters, counts: Counter) -> list[Estimator]:
    """The named estimators on one prepared map; the filters share one likelihood."""
    names = list(names)
    unknown = sorted(set(names) - set(ESTIMATORS))
    if unknown or not names:
        raise ValueError(f"estimators must be some of {ESTIMATORS}, got {names!r}")
    likelihood = None
    if set(names) & {"pmf", "pf"}:
        map_error = params.map_error_m if params.map_error_m is not None else map_error_estimate(prepared.grid.depth_m)
        sigma = math.hypot(params.depth_noise_m, map_error)
        likelihood = TerrainLikelihood(prepared, sigma_m=sigma, depth_sigma_m=sigma, form=params.likelihood, backend=params.backend)
    made: list[Estimator] = []
    for name in names:
        if name == "lost":
            made.append(PatentEstimator(prepared, params, counts))
        elif name == "pmf":
            made.append(PointMassFilter(likelihood, params, grid=prepared.grid))
        else:
            made.append(ParticleFilter(likelihood, params, grid=prepared.grid, seed=params.seed))
    return made


def navigate(
    records: NavRecords,
    grid: Grid,
    params: NavParameters | None = None,
    *,
    estimators: Iterable[str] = ESTIMATORS,
    prepared: PreparedMap | None = None,
    progress: Callable[[Iterable[int]], Iterable[int]] | None = None,
    profile: SoundSpeedProfile | None = None,
) -> NavResult:
    """Run the named estimators and both baselines over a tow.

    Parameters
    ----------
    records : NavRecords
        The tow's sensor records.
    grid : Grid
        The bathymetry, in the records' frame.
    params : NavParameters
        Constants; the defaults are the patent's nominal values where it gives them.
    estimators : names from :data:`ESTIMATORS`
        Which to run, each on the same records.
    prepared : PreparedMap, optional
        The grid already quantized (to reuse across runs); built from ``grid`` otherwise.
    progress : callable, optional
        Wraps the record loop's iterable (e.g. ``rich.progress.track``).
    profile : SoundSpeedProfile, optional
        The sound speed (``lost.host.usbl``): a record's USBL travel time is ray-traced from the
        transducer (``reference_depth_m``) to the vehicle's depth into the slant range, which wins over
        the record's straight-line ``slant_range_m`` (counted ``slant_range_ray_traced`` and, where both
        were there, ``slant_range_ray_over_straight``). A travel time the ray cannot explain (too short
        for the depth, below the profile) falls back to ``slant_range_m`` (``usbl_ray_failed``);
        travel times without a profile are not used (``usbl_travel_time_without_profile``).

    Raises
    ------
    ValueError
        Patch matching on a tow without sonar patches, a sonar patch on other nodes than the map, a
        prepared map of another grid, an unknown estimator.
    """
    params = params or NavParameters()
    prepared = prepared or PreparedMap(grid=grid, lsb_m=params.lsb_m)
    if prepared.grid is not grid:
        raise ValueError("the prepared map was made from another grid than the one given")
    if params.matching == "patch" and not any(patch is not None for patch in records.sonar):
        raise ValueError("the tow has no sonar patch, so patch matching has nothing to match; use matching='point'")
    other = sorted({float(p.node_m) for p in records.sonar if p is not None and not math.isclose(p.node_m, grid.node_m, rel_tol=1e-9)})
    if other:
        raise ValueError(f"the sonar patches have {', '.join(str(v) for v in other)} m nodes but the map {grid.node_m} m; "
                         "grid the patches on the map's nodes")
    counts: Counter = Counter()
    loop = _RecordLoop(records, params, make_estimators(estimators, prepared, params, counts), counts, profile)
    iterator: Iterable[int] = range(len(records))
    if progress is not None:
        iterator = progress(iterator)
    for n in iterator:
        loop.step(n)
    return loop.result()


class _RecordLoop:
    """The shared per-record work: velocity held, depth held, lay-back, start, baselines, estimators."""

    def __init__(self, records: NavRecords, params: NavParameters, estimators: list[Estimator], counts: Counter,
                 profile: SoundSpeedProfile | None = None) -> None:
        n = len(records)
        self._records, self._p, self._estimators, self.counts = records, params, estimators, counts
        self._profile = profile
        self._sonar = records.sonar if records.sonar else (None,) * n
        self._velocity = np.zeros(2)
        self._last_depth = float("nan")
        self._dead: np.ndarray | None = None
        self.layback, self.dead_reckoning = np.full((n, 2), np.nan), np.full((n, 2), np.nan)
        self.tracks = {e.name: FilterTrack.empty(n) for e in estimators}
        self.patent = {"predicted": np.full((n, 2), np.nan), "mle": np.full((n, 2), np.nan), "cat": np.full((n, 2), np.nan),
                       "distinctness": np.full(n, np.nan), "cross_velocity_mps": np.full(n, np.nan),
                       "slant_corrected": np.zeros(n, bool), "off_map": np.zeros(n, bool), "mle_source": np.full(n, "", dtype="<U5")}

    def step(self, n: int) -> None:
        records = self._records
        frame = _frame(records, n)
        measured = np.array([records.vel_x_mps[n], records.vel_y_mps[n]])
        held = not np.all(np.isfinite(measured))
        if not held:
            self._velocity = measured
        elif self._dead is not None:
            self.counts["velocity_held"] += 1
        depth = float(records.vehicle_depth_m[n])
        if np.isfinite(depth):
            self._last_depth = depth
        distance = layback_distance(float(records.cable_out_m[n]), self._last_depth, self._p)
        if frame is not None and np.isfinite(distance):
            self.layback[n] = layback_position(frame, distance)
        fix = records.usbl_fix(n)
        observation = Observation(t_s=float(records.t_s[n]), frame=frame, patch=self._sonar[n],
                                  ocean_depth_m=depth + float(records.altitude_m[n]), vehicle_depth_m=self._last_depth,
                                  slant_range_m=self._slant_range(n), fix_position_m=None if fix is None else fix[0],
                                  fix_covariance_m2=None if fix is None else fix[1],
                                  layback_m=self.layback[n].copy() if np.all(np.isfinite(self.layback[n])) else None)
        if self._dead is None:
            # Initialization: the lay-back model (cross-track zero), plus the requested offset.
            if not np.all(np.isfinite(self.layback[n])):
                self.counts["before_initialization"] += 1
                return
            self._dead = start = self.layback[n] + np.array(self._p.initial_offset_m)
            self.dead_reckoning[n] = start
            for estimator in self._estimators:
                estimator.start(observation.t_s, start, observation)
                self._record(n, estimator, 0.0)
            return
        motion = Motion(dt_s=observation.t_s - float(records.t_s[n - 1]), velocity_mps=self._velocity, held=held)
        self.dead_reckoning[n] = self._dead = state_update(self._dead, self._velocity, motion.dt_s)
        for estimator in self._estimators:
            begin = time.perf_counter()
            estimator.predict(motion)
            estimator.update(observation)
            self._record(n, estimator, (time.perf_counter() - begin) * 1e3)

    def _slant_range(self, n: int) -> float:
        """The record's slant range: ray-traced from its USBL travel time when there is a profile, else the straight one."""
        straight, travel = float(self._records.slant_range_m[n]), float(self._records.usbl_travel_time_s[n])
        if not math.isfinite(travel):
            return straight
        if self._profile is None:
            self.counts["usbl_travel_time_without_profile"] += 1
            return straight
        from ..usbl.rays import slant_range_from_travel_time  # lazily: gsw and pandas load only for a USBL run

        try:
            slant, _ = slant_range_from_travel_time(self._profile, travel, self._p.reference_depth_m, self._last_depth)
        except ValueError:  # too short for the depth, below the profile, a depth not yet measured: not this ray
            self.counts["usbl_ray_failed"] += 1
            return straight
        self.counts["slant_range_ray_traced"] += 1
        if math.isfinite(straight):
            self.counts["slant_range_ray_over_straight"] += 1
        return slant

    def _record(self, n: int, estimator: Estimator, ms: float) -> None:
        answer = estimator.estimate()
        track = self.tracks[estimator.name]
        track.position[n], track.covariance[n], track.usable[n] = answer.position, answer.covariance, answer.usable
        track.stage[n], track.nis[n], track.rejected[n], track.ms[n] = answer.stage, answer.nis, answer.rejected, ms
        track.depth_bias_m[n] = answer.depth_bias_m
        track.velocity_bias_mps[n], track.velocity_bias_sigma_mps[n] = answer.velocity_bias_mps, answer.velocity_bias_sigma_mps
        if isinstance(estimator, PatentEstimator):
            last = estimator.last
            self.patent["predicted"][n] = last["predicted"]
            if "mle" in last:
                if last["mle"] is not None:
                    self.patent["mle"][n] = last["mle"]
                    self.patent["mle_source"][n] = self._p.matching
                if last["cat"] is not None:
                    self.patent["cat"][n] = last["cat"]
                self.patent["distinctness"][n] = last["distinctness"]
                self.patent["cross_velocity_mps"][n] = last["cross_velocity_mps"]
                self.patent["slant_corrected"][n] = last["slant_corrected"]
                self.patent["off_map"][n] = last["off_map"]

    def result(self) -> NavResult:
        records, patent = self._records, self.patent
        truth = np.column_stack([records.truth_x_m, records.truth_y_m]) if records.has_truth else None
        self.counts["records"] = len(records)
        self.counts["mle_updates"] = int(np.count_nonzero(patent["mle_source"] != ""))
        self.counts["slant_range_corrections"] = int(patent["slant_corrected"].sum())
        lost = self.tracks.get("lost")
        tracks = {name: FilterTrack(**{**track.__dict__, "counts": dict(self._counts_of(name))}) for name, track in self.tracks.items()}
        return NavResult(
            t_s=np.asarray(records.t_s, float),
            estimate=lost.position if lost is not None else np.full((len(records), 2), np.nan),
            predicted=patent["predicted"], mle=patent["mle"], mle_source=patent["mle_source"], distinctness=patent["distinctness"],
            cat=patent["cat"], cross_velocity_mps=patent["cross_velocity_mps"], slant_corrected=patent["slant_corrected"],
            off_map=patent["off_map"], layback=self.layback, dead_reckoning=self.dead_reckoning, truth=truth,
            counts=dict(self.counts), tracks=tracks,
        )

    def _counts_of(self, name: str) -> Counter:
        for estimator in self._estimators:
            if estimator.name == name:
                return estimator.counts
        return Counter()
