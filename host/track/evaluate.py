"""Scoring a tracker's reports against the simulator's truth with Stone Soup's metrics, and our lock rule.

- GOSPA (alpha = 2, cutoff ``cutoff_m``, order ``p``) and OSPA are Stone Soup's (``GOSPAMetric``,
  ``OSPAMetric``), computed at every ping between the reported contacts and the targets then in the sector,
  and averaged over the pings (two empty sets score 0).
- SIAP (completeness, ambiguity, spuriousness, positional and velocity accuracy, longest track segment) is
  Stone Soup's ``SIAPMetrics`` over the whole run, tracks tied to truths by its ``TrackToTruth`` associator
  within ``LOCK_RADIUS_M``.
- Lock (:func:`.metrics.pings_to_lock`) per target, on the distance from the target to the nearest reported
  contact at each ping.
- A false track is a reported identity that spent most of its reported life farther than ``cutoff_m`` from
  every target in the sector.
- GOSPA per ping (:attr:`Score.gospa_per_ping`), so a mean and a percentile can be taken over the pings that
  hold a contact rather than over a diver-free hour of zeros.

Holding (:func:`holding`), the yardstick fair to every tracker, whatever its lock or confirmation rule: at
each ping the reported contacts are assigned one to one to the targets in the sector (Hungarian, on the
distance), an assignment within ``radius_m`` (25 m) *holding* that target. From it (:func:`contact_metrics`):
a target's *coverage* (share of its in-sector pings held), its *first lock* (in-sector pings until it is
first held, 1-based), its *identity switches* (changes of the identity holding it from one held ping to
the next), and the share of pings at which every target in the sector is held at once (two divers, two
tracks: one track between them holds only one).
"""

from __future__ import annotations

import datetime
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from .estimates import Estimate
from .metrics import LOCK_RADIUS_M, pings_to_lock
from .simulate import Truth

__all__ = ["Score", "score", "holding", "contact_metrics", "GOSPA_CUTOFF_M", "GOSPA_ORDER"]

#: GOSPA's cutoff: a contact farther than this from a target is a miss and a false one (half the cutoff each, alpha = 2).
GOSPA_CUTOFF_M = 50.0
GOSPA_ORDER = 1
_EPOCH = datetime.datetime(2000, 1, 1)


@dataclass(frozen=True)
class Score:
    """How a tracker did on one simulated run (module docstring)."""

    pings: int
    pings_to_lock: list[int | None]
    confirmed_tracks: int
    false_tracks: int
    gospa_mean: float
    gospa_localisation_mean: float
    gospa_missed_mean: float
    gospa_false_mean: float  # the three parts are GOSPA's own (metres^p; missed and false cost cutoff^p / 2 each)
    ospa_mean: float
    siap: dict[str, float] = field(default_factory=dict)
    gospa_per_ping: list[float] = field(default_factory=list, repr=False)

    def as_dict(self) -> dict:
        return asdict(self)


def _states(estimates: Sequence[Estimate], stamp: datetime.datetime) -> list:
    from stonesoup.types.state import State

    return [State([e.x_m, e.y_m, e.vx_mps, e.vy_mps], timestamp=stamp) for e in estimates]


def _truth_states(truth: Truth, i: int, stamp: datetime.datetime) -> list:
    from stonesoup.types.groundtruth import GroundTruthState

    seen = np.flatnonzero(truth.in_sector[i])
    return [GroundTruthState([*truth.xy[i, k], *truth.velocity[i, k]], timestamp=stamp, metadata={"target": int(k)}) for k in seen]


def _siap(history: Sequence[Sequence[Estimate]], truth: Truth, stamps: list[datetime.datetime]) -> dict[str, float]:
    from stonesoup.dataassociator.tracktotrack import TrackToTruth
    from stonesoup.measures import Euclidean
    from stonesoup.metricgenerator.manager import MultiManager
    from stonesoup.metricgenerator.tracktotruthmetrics import SIAPMetrics
    from stonesoup.types.groundtruth import GroundTruthPath
    from stonesoup.types.track import Track

    # Stone Soup's SIAP reads a track at every time within its association, so an identity that drops out and
    # comes back (a GM-PHD component dipping under its extraction weight) is scored as one segment per stretch.
    tracks: dict[tuple[int, int], list] = defaultdict(list)
    last_ping: dict[int, int] = {}
    segment: dict[int, int] = defaultdict(int)
    for i, (estimates, stamp) in enumerate(zip(history, stamps)):
        for e, state in zip(estimates, _states(estimates, stamp)):
            if last_ping.get(e.track_id) == i:
                continue  # one state per identity and ping
            if e.track_id in last_ping and last_ping[e.track_id] != i - 1:
                segment[e.track_id] += 1
            last_ping[e.track_id] = i
            tracks[(e.track_id, segment[e.track_id])].append(state)
    paths: dict[int, list] = defaultdict(list)
    for i, stamp in enumerate(stamps):
        for state in _truth_states(truth, i, stamp):
            paths[state.metadata["target"]].append(state)
    if not tracks or not paths:
        return {}
    siap = SIAPMetrics(position_measure=Euclidean((0, 1)), velocity_measure=Euclidean((2, 3)))
    manager = MultiManager([siap], associator=TrackToTruth(association_threshold=LOCK_RADIUS_M, measure=Euclidean((0, 1))))
    manager.add_data({"tracks": [Track(states, id=f"{k[0]}.{k[1]}") for k, states in tracks.items()],
                      "groundtruth_paths": [GroundTruthPath(states, id=str(k)) for k, states in paths.items()]})
    metrics = manager.generate_metrics()["siap_generator"]
    out = {}
    for title, metric in metrics.items():
        if not isinstance(metric.value, list):
            out[title.removeprefix("SIAP ")] = float(metric.value)
    return out


def score(history: Sequence[Sequence[Estimate]], truth: Truth, *, cutoff_m: float = GOSPA_CUTOFF_M, order: int = GOSPA_ORDER,
          siap: bool = True) -> Score:
    """Score per-ping reports ``history`` (one list of contacts per ping) against ``truth``."""
    from stonesoup.measures import Euclidean
    from stonesoup.metricgenerator.ospametric import GOSPAMetric, OSPAMetric

    if len(history) != truth.t_s.size:
        raise ValueError(f"{len(history)} pings of reports against {truth.t_s.size} pings of truth")
    measure = Euclidean((0, 1))
    gospa = GOSPAMetric(c=cutoff_m, p=order, measure=measure)
    ospa = OSPAMetric(c=cutoff_m, p=order, measure=measure)
    stamps = [_EPOCH + datetime.timedelta(seconds=float(t)) for t in truth.t_s]
    parts = np.zeros((len(history), 4))
    ospa_values = np.zeros(len(history))
    targets = truth.xy.shape[1]
    distance = np.full((len(history), targets), np.inf)
    far: dict[int, list[bool]] = defaultdict(list)
    for i, (estimates, stamp) in enumerate(zip(history, stamps)):
        measured, truths = _states(estimates, stamp), _truth_states(truth, i, stamp)
        if measured or truths:
            metric, _ = gospa.compute_gospa_metric(measured, truths)
            parts[i] = [metric.value[k] for k in ("distance", "localisation", "missed", "false")]
            ospa_values[i] = ospa.compute_OSPA_distance(measured, truths).value
        seen = truth.in_sector[i]
        for e in estimates:
            d = np.hypot(*(truth.xy[i] - e.xy).T)
            distance[i] = np.fmin(distance[i], np.where(np.isfinite(d), d, np.inf))
            far[e.track_id].append(not np.any(seen & (d <= cutoff_m)))
    locks = [pings_to_lock(distance[:, k], truth.in_sector[:, k]) for k in range(targets)]
    false_tracks = sum(1 for flags in far.values() if np.mean(flags) > 0.5)
    return Score(
        pings=len(history), pings_to_lock=locks, confirmed_tracks=len(far), false_tracks=false_tracks,
        gospa_mean=float(parts[:, 0].mean()), gospa_localisation_mean=float(parts[:, 1].mean()),
        gospa_missed_mean=float(parts[:, 2].mean()), gospa_false_mean=float(parts[:, 3].mean()),
        ospa_mean=float(ospa_values.mean()), siap=_siap(history, truth, stamps) if siap else {},
        gospa_per_ping=parts[:, 0].tolist(),
    )


def holding(history: Sequence[Sequence[Estimate]], truth: Truth, *, radius_m: float = LOCK_RADIUS_M) -> np.ndarray:
    """The identity holding each target at each ping, (pings, targets), -1 where none (module docstring)."""
    from scipy.optimize import linear_sum_assignment

    held = np.full(truth.in_sector.shape, -1)
    for i, estimates in enumerate(history):
        seen = np.flatnonzero(truth.in_sector[i])
        if not estimates or not seen.size:
            continue
        xy = np.array([e.xy for e in estimates])
        d = np.hypot(*(xy[:, None, :] - truth.xy[i, seen][None, :, :]).transpose(2, 0, 1))
        rows, cols = linear_sum_assignment(np.where(d <= radius_m, d, 1e9))
        for r, c in zip(rows, cols):
            if d[r, c] <= radius_m:
                held[i, seen[c]] = estimates[r].track_id
    return held


def contact_metrics(history: Sequence[Sequence[Estimate]], truth: Truth, *, radius_m: float = LOCK_RADIUS_M, after: int = 0) -> dict:
    """Coverage, first lock and identity switches per target, and the share of pings all targets are held at once.

    ``after`` leaves out each target's first so many in-sector pings from the coverage and the all-held share.
    """
    held = holding(history, truth, radius_m=radius_m)
    coverage, first_lock, switches = [], [], []
    judged_all = np.zeros(len(history), dtype=bool)
    for k in range(truth.xy.shape[1]):
        inside = np.flatnonzero(truth.in_sector[:, k])
        ids = held[inside, k]
        hit = np.flatnonzero(ids >= 0)
        first_lock.append(int(hit[0]) + 1 if hit.size else None)
        coverage.append(float(np.mean(ids[after:] >= 0)) if ids[after:].size else None)
        switches.append(int(np.count_nonzero(np.diff(ids[hit]))))
        judged_all[inside[after:]] = True
    all_in = truth.in_sector.all(axis=1) & judged_all
    together = float(np.mean((held[all_in] >= 0).all(axis=1))) if all_in.any() else None
    return {"coverage": coverage, "first_lock": first_lock, "identity_switches": switches, "all_held": together}
