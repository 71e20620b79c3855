"""Every constant of the navigation in one frozen, validated value: :class:`NavParameters`.

:func:`navigation_parameters` builds one from a settings table (a TOML ``[navigation]`` table or the
command line's), names and types checked by :mod:`lost.host.config`'s strict schema, ranges by the class.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

from ..config import ConfigError, validate_fields
from ..correlator import BACKENDS
from .likelihood import LIKELIHOODS, MAX_PHASES
from .mapprep import MAX_HOLE_SHARE
from .stages import CrossTrackTracker

__all__ = ["NavParameters", "navigation_parameters", "MATCHING", "LAYBACK_MODELS", "MAP_ERROR_MODELS"]

MATCHING = ("patch", "point")
LAYBACK_MODELS = ("cable", "depth_ratio")
MAP_ERROR_MODELS = ("per_node", "uniform")
#: An INS/DVL's velocity-bias walk, m/s per square-root second: the default, and the least the particle filter's
#: adapted walk takes (``lost.host.nav.pf``).
INS_VELOCITY_BIAS_WALK_MPS = 0.0005


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
        single ambiguous matches on smooth terrain pull the estimate (docs/patent.md).
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
        more matches where the floor turns smooth (on ``two_hour`` 1.2 changes the RMS by a few tenths of a
        metre either way, docs/patent.md). Not in the patent.
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
    map_error_model : {"per_node", "uniform"}
        How the map's error enters the likelihood when ``map_error_m`` is None. ``"per_node"``: each node
        carries its own (survey noise, the slope and the relief its spacing cannot show, from the map
        itself; :mod:`lost.host.nav.maperror`), and each placement's sigma follows the nodes under the
        patch. ``"uniform"``: one number for the whole map (``likelihood.map_error_estimate``).
    survey_sigma_m : float
        The survey noise of a map node, metres, where the grid carries no uncertainty layer of its own
        (``PreparedMap(node_sigma_m=...)``); for ``map_error_model = "per_node"``. Default 0.5.
    likelihood : {"laplace", "gaussian"}
        The residual distribution: Laplace uses the correlator's sum of absolute differences as the
        hardware gives it; Gaussian is eq. 3.4 (a sum of squares on the host).
    likelihood_weight : float
        Multiplies every terrain log-likelihood (after the new-share tempering). Default 1.
    likelihood_phases : int
        Samples of the terrain likelihood per map node and axis between the correlator's whole-node placements, from the
        patch's soundings gridded again on lattices moved by 1/K of a node (K - 1 more correlations of the record per
        axis: K**2 in all; patches without soundings read the placements alone). Default 3; 1 to 4.
    temper_by_correlation : bool
        Temper each terrain log-likelihood by the share of the patch's nodes whose residuals are independent
        (N_eff / n, learned from the residuals at the estimate while the density is narrow;
        :meth:`~lost.host.nav.likelihood.TerrainLikelihood.independent_share`). Default True.
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
    compensate_patch_motion : bool
        Grid a patch that carries its soundings again with each sounding placed by its own age and the
        velocity bias of the record before (:mod:`lost.host.nav.motion`): the dead reckoning inside a patch
        gathered over tens of seconds undone. Default True.
    velocity_bias_sigma_mps, velocity_bias_walk_mps : float
        The prior on the velocity bias (1-sigma, m/s) and its random walk (m/s per square-root second),
        for both filters: the particles' bias state and the point-mass filter's bias filter. A walk above an
        INS/DVL's (0.0005) is the particle filter's while it acquires; once settled it adapts to the terrain's
        corrections (:mod:`lost.host.nav.pf`).
    depth_bias_sigma_m, depth_bias_walk_m : float
        The single-depth (point) form's depth bias, measured ocean depth minus the map (tide, a
        pressure-depth error, a datum): its prior 1-sigma, metres, and its random walk, metres per
        square-root second. Defaults 3 m and 0.002 (0.2 m in three hours). The patch form needs no
        such state: mean compensation removes a constant bias.
    slant_range_sigma_m : float
        1-sigma of a slant range for the filters, which take it as a measurement (gated), not as the
        patent's correction.
    slant_range_dof : float
        Degrees of freedom of the Student-t a slant range is read with while the filter is usable (``inf``:
        Gaussian; while acquiring, always Gaussian: there the ranges must move a wide density, and a t's heavy
        tails keep the places the ring rules out). Default 6; more than 2.
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
        Smallest cell, metres; None: the coarser of a tenth of a map node and half the density's floor width, and off
        the map half the density's narrowest sigma (the slant ranges hold an axis under the floor there).
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
    drift_gate : float or None
        The drift test of the usable flag: the sum of the last ``usable_updates`` terrain updates' shifts of
        the mean against the sum of their expected covariances (``P_prior - P_post`` each) is chi-square with
        2 degrees of freedom for a consistent filter; above this the density is trailing the truth and the
        flag stays down (counted ``corrections_drifting``). Default 13.8 (0.999); None: no test, nor the trail test
        beside it (the same window's shifts one way along an axis, whose steady-state lag exceeds two of the density's
        sigmas: ``lost.host.nav.trust.Trust._one_way``, counted ``corrections_one_way`` too).
    max_hole_share : float
        A placement may put up to this share of a patch's valid soundings on map holes, which then count
        against the fill (the nearest depth, ``PreparedMap``); beyond it the placement is refused. Holes under
        nodes without a sounding never count. Default 0.1 (measured on ``short`` and ``shelf_canyon``: see
        ``lost.host.nav.mapprep.MAX_HOLE_SHARE``); 0: any sounding on a hole refuses the placement.
    reinit_after : int
        Terrain updates refused among the last ``2 reinit_after`` before the filter re-initializes. Default 10.
    off_map_usable_s : float
        Off the map (a patch or depth wholly off it, or a narrow density at its edge) a filter
        dead-reckons; once it has had neither a terrain update nor a position fix for this long it is
        no longer usable (counted ``unusable_off_map``). Default 10 s. Without it a tow leaving its map
        was flagged usable for minutes while dead reckoning took it tens of metres off.
    max_patch_age_s : float
        The oldest plausible sonar patch, seconds: a patch reckoned back further than this, or to a
        negative age, is not used (counted ``patch_age_implausible``). The misplacement a velocity-bias
        error causes grows with the age squared; an age of 1e7 s in a log would blow a filter's density
        to kilometres. Default 600 s (a real-time patch is built over tens of seconds).
    seed : int
        The particle filter's random stream.

    The USBL (records with ``usbl_*`` series; see ``navigate``'s ``profile`` for the ray-traced range)
    --------------------------------------------------------------------------------------------------
    use_usbl_fix : bool
        Use the records' USBL fixes: the Bayesian filters as a position measurement with the fix's covariance
        (``usbl_fix_dof``; gated by ``gate_nis``, counted ``fix_updates``, ``fix_rejected_gate``; the
        record's slant range is then not used again, ``range_in_fix``); the patent pipeline to
        re-centre its dead reckoning when it has had no MLE for ``cat_restart_s``. Default True.
    usbl_fix_dof : float
        Degrees of freedom of the Student-t a USBL fix is read with, its covariance the scale (``inf``: Gaussian).
        Real fixes have heavy tails (multipath, refraction); on ``usbl_nav``, whose fixes are ray-traced through a
        cast the processing does not know, 2-3 % lie beyond chi-square's 99.9 % (13.8) and their median normalized
        error is 1.41-1.51, as a t of 6 degrees of freedom has it (2.8 %, 1.56). Default 6; more than 2.
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
    map_error_model: str = "per_node"
    survey_sigma_m: float = 0.5
    likelihood: str = "laplace"
    likelihood_weight: float = 1.0
    likelihood_phases: int = 3
    temper_by_correlation: bool = True
    initial_sigma_m: float = 300.0
    velocity_noise_mps: float = 0.05
    gyro_bias_rps: float = math.radians(0.01) / 3600.0
    accel_bias_mps2: float = 10e-6 * 9.81
    estimate_velocity_bias: bool = True
    bias_learning_updates: int = 5
    compensate_patch_motion: bool = True
    velocity_bias_sigma_mps: float = 0.05
    velocity_bias_walk_mps: float = INS_VELOCITY_BIAS_WALK_MPS
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
    drift_gate: float | None = 13.8
    max_hole_share: float = MAX_HOLE_SHARE
    reinit_after: int = 10
    off_map_usable_s: float = 10.0
    max_patch_age_s: float = 600.0
    seed: int = 0
    use_usbl_fix: bool = True
    usbl_fix_dof: float = 6.0
    slant_range_dof: float = 6.0

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
        if self.map_error_model not in MAP_ERROR_MODELS:
            raise ValueError(f"map_error_model must be one of {MAP_ERROR_MODELS}, got {self.map_error_model!r}.")
        if self.likelihood not in LIKELIHOODS:
            raise ValueError(f"likelihood must be one of {LIKELIHOODS}, got {self.likelihood!r}.")
        for name in ("depth_noise_m", "likelihood_weight", "initial_sigma_m", "slant_range_sigma_m", "pmf_sigmas", "gate_nis",
                     "misfit_gate", "usable_sigma_nodes", "lookalike_radius_m", "elsewhere_margin", "off_map_usable_s",
                     "max_patch_age_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite number, got {value!r}.")
        for name in ("position_floor_nodes", "position_floor_m", "position_floor_tracking_m", "pf_floor_tracking_m", "velocity_noise_mps",
                     "gyro_bias_rps", "accel_bias_mps2", "velocity_bias_sigma_mps",
                     "survey_sigma_m", "velocity_bias_walk_mps", "depth_bias_sigma_m", "depth_bias_walk_m"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a finite number, at least 0, got {value!r}.")
        for name in ("map_error_m", "pmf_min_cell_m", "drift_gate"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite number or None, got {value!r}.")
        for name, low in (("pmf_cells", 8), ("pf_particles", 10), ("usable_updates", 1), ("usable_updates_point", 1),
                          ("reinit_after", 1), ("bias_learning_updates", 1), ("likelihood_phases", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"{name} must be a whole number of at least {low}, got {value!r}.")
        if self.likelihood_phases > MAX_PHASES:
            raise ValueError(f"likelihood_phases must be at most {MAX_PHASES} (each is a correlation per axis), got {self.likelihood_phases!r}.")
        for name in ("usbl_fix_dof", "slant_range_dof"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and value > 2.0):
                raise ValueError(f"{name} must be a number of degrees of freedom over 2 (inf: Gaussian), got {value!r}.")
        if not (math.isfinite(self.min_distinctness) and self.min_distinctness >= 0.0):
            raise ValueError(f"min_distinctness must be a finite number, at least 0 (0 disables the test), got {self.min_distinctness!r}.")
        if not (isinstance(self.max_hole_share, (int, float)) and 0.0 <= self.max_hole_share < 1.0):
            raise ValueError(f"max_hole_share must lie in [0, 1), got {self.max_hole_share!r}.")
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


def navigation_parameters(table: Mapping[str, Any], where: str = "navigation") -> NavParameters:
    """A :class:`NavParameters` from settings validated strictly (names and types by the schema, ranges by the class).

    Raises
    ------
    ConfigError
        A setting is unknown or of the wrong type (named by path), or NavParameters refuses its
        value or range (its message, prefixed with ``where``).
    """
    values = validate_fields(NavParameters, table, where)
    try:
        return NavParameters(**values)
    except (TypeError, ValueError) as error:
        raise ConfigError(f"[{where}]: {error}") from None
