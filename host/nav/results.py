"""What a navigation run returns: every estimator's :class:`FilterTrack` and the run's :class:`NavResult`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["FilterTrack", "NavResult"]


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
    held : (N,) bool array, the estimate was held within dead reckoning's 3 sigma (:mod:`lost.host.nav.guard`)
    reinitialized : (N,) str array, the cause of a re-initialization at that record ("" when none)
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
    held: np.ndarray | None = None
    reinitialized: np.ndarray | None = None

    @classmethod
    def empty(cls, n: int) -> FilterTrack:
        return cls(np.full((n, 2), np.nan), np.full((n, 2, 2), np.nan), np.zeros(n, bool), np.full(n, "uninitialized", dtype="<U14"),
                   np.full(n, np.nan), np.full(n, "", dtype="<U32"), np.full(n, np.nan), np.full(n, np.nan), np.full((n, 2), np.nan),
                   np.full((n, 2), np.nan), held=np.zeros(n, bool), reinitialized=np.full(n, "", dtype="<U24"))


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

