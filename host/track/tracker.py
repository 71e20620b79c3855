"""Several contacts in clutter: the paper's particle cloud finds them, EM splits it, one filtered track each.

Each ping, in order:

1. Every track is predicted to the ping (nearly constant velocity), its probability of existence ``r`` with
   it (a contact stays with probability ``exp(-dt / track_lifetime_s)``). The tracks are then updated
   together by joint integrated probabilistic data association (:mod:`.association`): for the tracks
   whose gates share detections every joint assignment is weighed, so one detection never feeds two
   tracks, and each track's existence follows from the detection probability ``pd`` (0 outside the
   sector) and the Poisson clutter density. The states are updated from JPDA*'s events
   (``permutation_pruning``: of the joint events that differ only by which of them took which detection,
   the likeliest), so two tracks on contacts closer than their gates are not pulled together. The
   probability that a detection is some track's is its *claim*; a detection claimed with at least
   ``claim_probability`` is spared to the search cloud. Where the detector reports strengths, each
   detection's spatial density is scaled by its amplitude likelihood ratio (:mod:`.amplitude`).
2. The search cloud, the paper's filter (:class:`~.particle.DiverParticleFilter`) with the Poisson-clutter
   floor, steps on the *unclaimed* detections, so it hunts for contacts no track holds yet; a share of it
   (``reseed_fraction``) is drawn afresh over the sector each ping so that no corner goes unwatched. Each
   detection's pull on it is scaled by its amplitude ratio (``cloud_amplitude``), so a strong return
   gathers the cloud at its first ping.
3. The cloud is clustered by expectation-maximization (:mod:`.cluster`), started at the unclaimed
   detections. A cluster holding at least ``birth_share`` of the cloud and no wider than ``birth_spread_m``
   is a contact the cloud has followed over consecutive pings (one ping's clutter holds a few per cent; a
   repeated return holds most of it): a *tentative* track is born at each unclaimed detection inside the
   cluster's 99 % ellipse (one cluster may hold two contacts side by side), nearest the centre first, with
   the measurement's covariance, an unknown velocity and existence ``birth_existence``, unless that
   detection lies within ``birth_exclusion_m`` of a track. A second contact beside a track (a diver who
   splits from another) is born this way: its detections are the ones the joint association leaves
   unclaimed.
4. Track management from the existence alone: a tentative track is *confirmed* when its existence reaches
   ``confirm_existence``, and deleted when it falls below ``delete_tentative_existence``; a confirmed track is
   deleted below ``delete_confirmed_existence`` or when its position is known worse than
   ``max_position_sigma_m``. How many missed pings that takes follows from ``pd`` and the clutter (a miss
   weighs less against a contact seldom detected). Two tracks closer than ``merge_chi2`` (squared
   Mahalanobis distance of their positions) follow one contact: the elder keeps it. Identities are
   never reused.

A confirmed track whose prediction lies outside the sector (a contact the platform's swing has left
behind) is kept, its existence decaying only by its lifetime, and reported with the status ``outside``
rather than as a contact until it is seen again. Each track carries its covariance; from it come the speed, heading, closest point of approach to the sonar
(relative to the platform's own motion from GPS), the time to come within ``reach_radius_m`` of it, and a
class from the speed once it is known to ``class_speed_sigma_mps``: below ``drifting_below_mps`` a drifting
object, above ``animal_above_mps`` a fast animal, between them a diver.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from .amplitude import amplitude_ratio
from .association import associate
from .cluster import fit_mixture
from .detections import Ping
from .geometry import Sonar, polar_to_world, world_to_polar
from .kalman import GATE_CHI2, ContactState, innovations, pda_combine, predict
from .particle import DiverParticleFilter, PaperParameters, clutter_floor

__all__ = ["TrackerParameters", "Track", "TrackReport", "MultiTargetTracker", "CLASSES"]

CLASSES = ("unknown", "drifting", "diver", "fast animal")


@dataclass(frozen=True, kw_only=True)
class TrackerParameters:
    """Everything the multi-target tracker assumes (module docstring), with the defaults of the paper's sonar.

    The sonar model (``pd``, ``clutter_per_ping``, ``range_sigma_m``, ``bearing_sigma_deg``) should be the
    detector's; the defaults are the simulator's. ``accel_sigma`` (m/s^1.5) covers a diver's changes of
    course; ``initial_speed_sigma_mps`` a newborn track's unknown velocity. The strength model
    (``amplitude``, ``target_strength_db``, ``clutter_strength_db``, their sigmas, ``max_amplitude_ratio``;
    :mod:`.amplitude`) is in dB above the detection threshold; the defaults are the moments of the
    simulator's strengths at pd 0.9 and its default clutter (:func:`.simulate.strength_moments`), whose
    distributions are not Gaussian.
    """

    particles: int = 10_000
    reseed_fraction: float = 0.1
    pd: float = 0.9
    clutter_per_ping: float = 5.0
    range_sigma_m: float = 2.0
    bearing_sigma_deg: float = 1.5
    accel_sigma: float = 0.02
    initial_speed_sigma_mps: float = 1.5
    em_points: int = 1000
    birth_share: float = 0.25
    birth_spread_m: float = 25.0
    birth_exclusion_m: float = 10.0
    claim_probability: float = 0.5
    track_lifetime_s: float = 600.0
    birth_existence: float = 0.05
    confirm_existence: float = 0.9999
    delete_tentative_existence: float = 0.002
    delete_confirmed_existence: float = 0.01
    merge_chi2: float = 0.5
    permutation_pruning: bool = True
    amplitude: bool = True
    target_strength_db: float = 8.6
    target_strength_sigma_db: float = 3.9
    clutter_strength_db: float = 2.3
    clutter_strength_sigma_db: float = 2.1
    max_amplitude_ratio: float = 100.0
    cloud_amplitude: bool = True
    max_position_sigma_m: float = 60.0
    reach_radius_m: float = 10.0
    class_speed_sigma_mps: float = 0.15
    drifting_below_mps: float = 0.3
    animal_above_mps: float = 2.0

    def __post_init__(self) -> None:
        if not (0 < self.pd <= 1) or self.clutter_per_ping <= 0:
            raise ValueError(f"The tracker needs pd in (0, 1] and a positive clutter rate, got {self.pd!r} and {self.clutter_per_ping!r}.")
        if not (0 < self.delete_tentative_existence < self.birth_existence < self.confirm_existence < 1
                and 0 < self.delete_confirmed_existence < self.confirm_existence):
            raise ValueError(
                "Existence thresholds need 0 < delete_tentative_existence < birth_existence < confirm_existence < 1 and "
                f"0 < delete_confirmed_existence < confirm_existence, got {self.delete_tentative_existence!r}, {self.birth_existence!r}, "
                f"{self.confirm_existence!r}, {self.delete_confirmed_existence!r}.")
        if not (0 < self.claim_probability <= 1) or self.track_lifetime_s <= 0:
            raise ValueError(f"claim_probability must be in (0, 1] and track_lifetime_s positive, got {self.claim_probability!r}, {self.track_lifetime_s!r}.")
        if min(self.target_strength_sigma_db, self.clutter_strength_sigma_db) <= 0 or not self.max_amplitude_ratio >= 1:
            raise ValueError("The strength model needs positive sigmas and max_amplitude_ratio >= 1, got "
                             f"{self.target_strength_sigma_db!r}, {self.clutter_strength_sigma_db!r}, {self.max_amplitude_ratio!r}.")
        if not (0 <= self.reseed_fraction < 1) or self.particles < 10:
            raise ValueError(f"reseed_fraction must be in [0, 1) and particles at least 10, got {self.reseed_fraction!r}, {self.particles!r}.")

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass
class Track:
    """One contact: its identity, filtered state, and the record confirmation and deletion read."""

    id: int
    state: ContactState
    born_ping: int
    existence: float
    confirmed: bool = False
    confirmed_ping: int | None = None


@dataclass(frozen=True)
class TrackReport:
    """A track after one ping, as ``tracks.csv`` writes it (NaN where not defined)."""

    ping: int
    t_s: float
    track_id: int
    status: str
    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float
    sd_x_m: float
    sd_y_m: float
    speed_mps: float
    heading_deg: float
    range_m: float
    bearing_deg: float
    classification: str
    cpa_m: float
    t_cpa_s: float
    time_to_reach_s: float
    existence: float
    covariance: np.ndarray = field(repr=False, compare=False)


def _cpa(p: np.ndarray, w: np.ndarray, reach_m: float) -> tuple[float, float, float]:
    """Closest approach of relative position ``p`` moving at ``w``: distance, time, and time to come within ``reach_m``."""
    w2 = float(w @ w)
    t_cpa = max(0.0, -float(p @ w) / w2) if w2 > 0 else 0.0
    cpa = float(np.hypot(*(p + w * t_cpa)))
    if float(np.hypot(*p)) <= reach_m:
        return cpa, t_cpa, 0.0
    if cpa > reach_m:
        return cpa, t_cpa, math.nan
    # |p + w t| = reach: the smaller root.
    b, c = float(p @ w), float(p @ p) - reach_m**2
    return cpa, t_cpa, (-b - math.sqrt(b * b - w2 * c)) / w2


class MultiTargetTracker:
    """The tracker of the module docstring, stepping ping by ping.

    Parameters
    ----------
    sonar : Sonar
        The sector.
    parameters : TrackerParameters
        Sonar model, birth, confirmation, deletion and classification settings.
    rng : numpy.random.Generator
        The only source of randomness.
    """

    def __init__(self, *, sonar: Sonar, parameters: TrackerParameters, rng: np.random.Generator) -> None:
        p = parameters
        self._sonar, self._p, self._rng = sonar, p, rng
        paper = PaperParameters(particles=p.particles)
        floor = clutter_floor(pd=p.pd, clutter_per_ping=p.clutter_per_ping, sonar=sonar,
                              bias_range_m=paper.bias_range_m, bias_bearing_deg=paper.bias_bearing_deg)
        self.cloud = DiverParticleFilter(sonar=sonar, parameters=PaperParameters(particles=p.particles, floor=floor), rng=rng)
        self._R = np.diag([p.range_sigma_m**2, math.radians(p.bearing_sigma_deg) ** 2])
        self._clutter_density = p.clutter_per_ping / sonar.polar_extent
        self.tracks: list[Track] = []
        self.deleted: list[Track] = []
        self._next_id = 1
        self._last: Ping | None = None
        self.step_ms: list[float] = []
        self.step_cpu_ms: list[float] = []  # this thread's CPU time: the step's cost on a machine shared with other work

    @property
    def parameters(self) -> TrackerParameters:
        return self._p

    @property
    def tracks_born(self) -> int:
        """Tentative tracks started so far (identities handed out)."""
        return self._next_id - 1

    def _in_sector(self, x: np.ndarray, ping: Ping) -> bool:
        r, b = world_to_polar(ping.platform_xy, ping.heading_deg, x[None, :2])
        return bool(self._sonar.inside(r, b)[0])

    def _update_tracks(self, ping: Ping, dt: float, ratio: np.ndarray) -> np.ndarray:
        """Predict every track and update them jointly (JIPDA); each detection's claim by the tracks."""
        z = np.column_stack((ping.range_m, np.radians(ping.bearing_deg)))
        p = self._p
        survival = math.exp(-dt / p.track_lifetime_s)
        innovations_ = []
        for track in self.tracks:
            if dt > 0:
                track.state = predict(track.state, dt, p.accel_sigma)
                track.existence *= survival
            innovations_.append(innovations(track.state, z, self._R, ping.platform_xy, ping.heading_deg))
        if not self.tracks:
            return np.zeros(ping.detections)
        # A strong return is likelier a contact's than clutter's: its ratio scales its spatial density (IPDA-AI).
        density = np.array([inn.density for inn in innovations_]).reshape(len(self.tracks), ping.detections)
        joint = associate(
            density * ratio[None, :],
            np.array([inn.gated for inn in innovations_]).reshape(len(self.tracks), ping.detections),
            np.array([t.existence for t in self.tracks]),
            np.array([p.pd if self._in_sector(t.state.x, ping) else 0.0 for t in self.tracks]),
            self._clutter_density, permutation_pruning=p.permutation_pruning)
        for k, (track, inn) in enumerate(zip(self.tracks, innovations_)):
            track.state = pda_combine(track.state, inn, joint.beta[k], float(joint.beta_none[k]))
            track.existence = float(joint.existence[k])
        return joint.claimed

    def _manage(self, ping: Ping) -> None:
        p, kept = self._p, []
        for track in self.tracks:
            if not track.confirmed and track.existence >= p.confirm_existence:
                track.confirmed, track.confirmed_ping = True, ping.index
            sigma = math.sqrt(max(np.linalg.eigvalsh(track.state.P[:2, :2])))
            floor = p.delete_confirmed_existence if track.confirmed else p.delete_tentative_existence
            lost = track.existence < floor or sigma > p.max_position_sigma_m
            (self.deleted if lost else kept).append(track)
        self.tracks = self._merge(kept)

    def _merge(self, tracks: list[Track]) -> list[Track]:
        """Two tracks on one contact (positions within ``merge_chi2`` of each other): the elder keeps it."""
        kept: list[Track] = []
        # Confirmed before tentative, then by age, so the identity that survives is the one already reported.
        for track in sorted(tracks, key=lambda t: (not t.confirmed, t.born_ping, t.id)):
            if any(self._same_contact(track, other, self._p.merge_chi2) for other in kept):
                self.deleted.append(track)
            else:
                kept.append(track)
        return sorted(kept, key=lambda t: t.id)

    @staticmethod
    def _same_contact(a: Track, b: Track, chi2: float) -> bool:
        d = a.state.x[:2] - b.state.x[:2]
        return float(d @ np.linalg.solve(a.state.P[:2, :2] + b.state.P[:2, :2], d)) < chi2

    def _births(self, ping: Ping, unclaimed: np.ndarray) -> None:
        p = self._p
        if not unclaimed.any():
            return
        cloud = self.cloud.xy
        sample = cloud[:: max(1, cloud.shape[0] // p.em_points)]  # resampled particles are in random order
        candidates = np.flatnonzero(unclaimed)
        detections_xy = ping.detections_xy()[candidates]
        mixture = fit_mixture(sample, detections_xy)
        for share, mean, cov in zip(mixture.shares, mixture.means, mixture.covariances):
            if share < p.birth_share or math.sqrt(max(np.linalg.eigvalsh(cov))) > p.birth_spread_m:
                continue
            # The cluster says contacts are there; the detections inside it say where, to the sensor's accuracy.
            # One cluster may hold two contacts side by side: each of its detections can start a track.
            offset = detections_xy - mean
            inside = np.einsum("ni,ij,nj->n", offset, np.linalg.inv(cov), offset) < GATE_CHI2
            for k in np.flatnonzero(inside)[np.argsort(np.hypot(*offset[inside].T))]:
                if any(np.hypot(*(detections_xy[k] - track.state.x[:2])) < p.birth_exclusion_m for track in self.tracks):
                    continue
                self.tracks.append(Track(self._next_id, self._newborn(ping, candidates[k]), ping.index, p.birth_existence))
                self._next_id += 1

    def _newborn(self, ping: Ping, detection: int) -> ContactState:
        """A track's start at one detection: its position and the measurement's covariance, velocity unknown."""
        r = ping.range_m[detection]
        azimuth = math.radians(ping.heading_deg + ping.bearing_deg[detection])
        x = np.concatenate((polar_to_world(ping.platform_xy, ping.heading_deg, ping.range_m[[detection]], ping.bearing_deg[[detection]])[0], [0.0, 0.0]))
        J = np.array([[math.sin(azimuth), r * math.cos(azimuth)], [math.cos(azimuth), -r * math.sin(azimuth)]])  # d(x, y)/d(r, b)
        P = np.zeros((4, 4))
        P[:2, :2] = J @ self._R @ J.T
        P[2:, 2:] = self._p.initial_speed_sigma_mps**2 * np.eye(2)
        return ContactState(x, P)

    def _reseed(self, ping: Ping) -> None:
        n = int(self._p.reseed_fraction * self.cloud.xy.shape[0])
        if n:
            which = self._rng.choice(self.cloud.xy.shape[0], size=n, replace=False)
            self.cloud.xy[which] = self.cloud.draw(n, ping)

    def step(self, ping: Ping) -> list[TrackReport]:
        """One ping through the tracker; a report of every live track (tentative ones included)."""
        start, start_cpu = time.perf_counter(), time.thread_time()
        dt = 0.0 if self._last is None else ping.t_s - self._last.t_s
        if self._last is not None and dt <= 0:
            raise ValueError(f"Ping {ping.index} at t = {ping.t_s!r} s does not come after ping {self._last.index} at {self._last.t_s!r} s.")
        ratio = amplitude_ratio(ping.strength_db, self._p)
        claimed = self._update_tracks(ping, dt, ratio) >= self._p.claim_probability
        pull = ratio[~claimed] if self._p.cloud_amplitude else None
        self.cloud.step(ping, range_m=ping.range_m[~claimed], bearing_deg=ping.bearing_deg[~claimed], detection_weights=pull)
        self._births(ping, ~claimed)
        self._manage(ping)
        self._reseed(ping)
        platform_velocity = np.zeros(2) if self._last is None or dt <= 0 else (ping.platform_xy - self._last.platform_xy) / dt
        self._last = ping
        reports = [self._report(track, ping, platform_velocity) for track in self.tracks]
        self.step_ms.append((time.perf_counter() - start) * 1e3)
        self.step_cpu_ms.append((time.thread_time() - start_cpu) * 1e3)
        return reports

    def _classify(self, v: np.ndarray, P: np.ndarray) -> str:
        p = self._p
        speed = float(np.hypot(*v))
        direction = v / speed if speed > 1e-9 else np.array([1.0, 0.0])
        speed_sigma = math.sqrt(float(direction @ P[2:, 2:] @ direction))
        if speed_sigma > p.class_speed_sigma_mps:
            return "unknown"
        if speed < p.drifting_below_mps:
            return "drifting"
        return "fast animal" if speed > p.animal_above_mps else "diver"

    def _report(self, track: Track, ping: Ping, platform_velocity: np.ndarray) -> TrackReport:
        x, P = track.state.x, track.state.P
        rel = x[:2] - ping.platform_xy
        cpa, t_cpa, reach = _cpa(rel, x[2:] - platform_velocity, self._p.reach_radius_m)
        bearing = (math.degrees(math.atan2(rel[0], rel[1])) - ping.heading_deg + 180) % 360 - 180
        return TrackReport(
            ping.index, ping.t_s, track.id, self._status(track, ping),
            float(x[0]), float(x[1]), float(x[2]), float(x[3]), math.sqrt(P[0, 0]), math.sqrt(P[1, 1]),
            float(np.hypot(x[2], x[3])), math.degrees(math.atan2(x[2], x[3])) % 360.0,
            float(np.hypot(*rel)), bearing, self._classify(x[2:], P), cpa, t_cpa, reach, track.existence, P.copy(),
        )

    def _status(self, track: Track, ping: Ping) -> str:
        """tentative; confirmed; or outside: confirmed but predicted outside the sector, kept without being reported as a contact."""
        if not track.confirmed:
            return "tentative"
        return "confirmed" if self._in_sector(track.state.x, ping) else "outside"

    def cloud_sample(self, n: int = 1000) -> np.ndarray:
        """Up to ``n`` of the search cloud's particles (for plots)."""
        xy = self.cloud.xy
        return xy if xy is None or xy.shape[0] <= n else xy[:: max(1, xy.shape[0] // n)]


