"""A recorded multibeam survey as the navigation's records: pings in, one record out per interval.

The platform is the surveying ship itself (a hull-mounted multibeam), so a record has no cable
(``cable_out_m`` 0) and no slant range. The file's positions are the truth (``truth_x_m``/``truth_y_m``)
and are not given to the navigation: it dead-reckons from the velocity of the file's positions,
differenced ping to ping, plus an injected velocity bias (``dr_bias_mps``), from the file's first
position plus an injected offset (``start_offset_m``); or, for a scripted dead reckoning (a simulated tow's own,
say), the reckoned position less the truth as a function of time (``dead_reckoning_error``). That dead-reckoned track is also the record's
``ship_x_m``/``ship_y_m`` (the frame the patent pipeline measures cross-track in, and the lay-back
model's start), so no record carries the truth to the estimators.

Each record closes an interval of ``interval_s`` seconds of pings (counted from the first ping); its time
is the interval's last ping's. Its patch is :func:`lost.host.io.sonar.grid_soundings` of the valid beams of
the pings of the last ``window_s`` seconds up to the record (default ``interval_s``: the interval's own
pings; longer, a patch that reaches along the track as well as across it; with ``full_window``, none until
``window_s`` seconds after the first ping: a window still filling is a strip of the swath, which can match the map
elsewhere), at the map's ``node_m``, placed relative to the vehicle at the record as the
navigation knows it: the beam's offset from its own ping plus the ping's position reckoned back from
the record over the ping's age (the true displacement plus the dead reckoning's error over the age: the
velocity bias times the age, as a dead-reckoned vehicle would place it), with the patch's ``age_s`` the soundings' mean age. The patch is
centred on the vehicle (``patch_centre="vehicle"``) or on the middle of the soundings (``"soundings"``).

That is the ``"window"`` rule (``patch_rule``). The ``"behind"`` rule is a ``"swath"`` scenario's real-time rule
(:mod:`lost.host.scenario.swath`), so that a simulated tow's file gives the scenario's own patches: of the pings of the
last ``window_s`` seconds (here the longest look back, the scenario's ``max_window_s``), the latest whose placed
position lies at least half a patch diagonal from the vehicle's is the centre (without one, the earliest); the patch
is centred on that ping and holds the pings up to the record, at most ``window_s`` seconds older than the centre,
placed within half a patch diagonal of it.

:class:`SurveyRecorder` is streaming: :meth:`~SurveyRecorder.add` takes one ping and returns the
records that ping closed; :meth:`~SurveyRecorder.finish` closes the last. :func:`survey_records` runs it
over a :class:`~lost.host.io.survey.Survey` into :class:`~lost.host.records.NavRecords`, the same value the
navigation log reader produces.

Counted, never silent (:attr:`SurveyRecorder.skipped`): a record interval whose pings have no valid beam
(the record is kept without a patch: the navigation dead-reckons through it); with ``full_window``, a record
before its window was full (kept without a patch); valid beams beyond the
patch; a ping earlier than a record already closed. Refused by name: a ping of a sonar head or ship not
seen in the first record (:class:`~lost.host.io.errors.DifferentShipsError`: files of different ships given
together).
"""

from __future__ import annotations

import math
from collections import Counter, deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..records import NavRecords, SonarPatch
from .errors import DifferentShipsError, NoPingsError, SurveyOffMapError
from .sonar import grid_soundings, soundings_centre
from .survey import Ping, Survey

__all__ = ["SurveyRecord", "SurveyRecorder", "survey_records", "nav_records", "check_survey_on_map", "SURVEY_PATCH_CENTRES", "SURVEY_PATCH_RULES",
           "DEFAULT_RECORD_S"]

SURVEY_PATCH_CENTRES = ("vehicle", "soundings")
#: Which pings make a record's patch: the last ``window_s`` seconds, or a swath scenario's real-time rule (see the module).
SURVEY_PATCH_RULES = ("window", "behind")
#: Ping times are compared to this, seconds: a format's millisecond, and a float's rounding of it.
_TIME_TOLERANCE_S = 2e-3
#: Seconds of pings per record when the caller names none (``lost run --survey``'s ``--record-s``).
DEFAULT_RECORD_S = 5.0


@dataclass(frozen=True)
class SurveyRecord:
    """One record of a recorded survey: the values of one row of :class:`~lost.host.records.NavRecords`."""

    t_s: float
    ship_x_m: float
    ship_y_m: float
    ship_heading_deg: float
    vehicle_depth_m: float
    altitude_m: float
    vel_x_mps: float
    vel_y_mps: float
    truth_x_m: float
    truth_y_m: float
    sonar: SonarPatch | None
    pings: int
    soundings: int


class SurveyRecorder:
    """Pings in, records out (see the module).

    Parameters
    ----------
    node_m : float
        The map's node spacing, metres: the patches' nodes.
    patch_shape : (rows, cols)
        Nodes of each record's patch, north by east.
    interval_s : float
        Seconds of pings per record.
    window_s : float, optional
        Seconds of pings up to a record that make its patch; default ``interval_s``.
    dr_bias_mps : (east, north)
        Added to the velocity the navigation dead-reckons with, m/s.
    start_offset_m : (east, north)
        The navigation's start less the file's first position, metres.
    dead_reckoning_error : callable, optional
        ``t`` (seconds from the first ping) to the dead-reckoned position less the true one, (east, north) metres:
        a scripted dead reckoning in place of ``dr_bias_mps`` and ``start_offset_m`` (which must then be zero).
        The records' track is the truth plus it, their velocity that track differenced, and each beam is placed
        by its difference between the ping and the record.
    patch_centre : {"vehicle", "soundings"}
        Where each record's patch is centred (``"window"`` rule; the ``"behind"`` rule centres it on its centre ping).
    patch_rule : {"window", "behind"}
        Which pings make a record's patch (see the module); with ``"behind"``, ``window_s`` is the longest look back.
    full_window : bool
        No patch for the records of the first ``window_s`` seconds (their window is still filling).
    """

    def __init__(self, *, node_m: float, patch_shape: tuple[int, int], interval_s: float, window_s: float | None = None,
                 dr_bias_mps=(0.0, 0.0), start_offset_m=(0.0, 0.0), dead_reckoning_error: Callable[[float], object] | None = None,
                 patch_centre: str = "vehicle", full_window: bool = False, patch_rule: str = "window") -> None:
        window_s = interval_s if window_s is None else window_s
        for name, value in (("interval_s", interval_s), ("window_s", window_s)):
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number of seconds, got {value!r}")
        if patch_centre not in SURVEY_PATCH_CENTRES:
            raise ValueError(f"patch_centre must be one of {SURVEY_PATCH_CENTRES}, got {patch_centre!r}")
        if patch_rule not in SURVEY_PATCH_RULES:
            raise ValueError(f"patch_rule must be one of {SURVEY_PATCH_RULES}, got {patch_rule!r}")
        if patch_rule == "behind" and patch_centre != "vehicle":
            raise ValueError(f"patch_rule 'behind' centres each patch on its centre ping; patch_centre {patch_centre!r} cannot be given with it")
        self.patch_rule = patch_rule
        self.node_m, self.patch_shape, self.patch_centre = float(node_m), tuple(patch_shape), patch_centre
        self.interval_s, self.window_s = float(interval_s), float(window_s)
        self.bias = _pair(dr_bias_mps, "dr_bias_mps")
        self.start_offset = _pair(start_offset_m, "start_offset_m")
        if dead_reckoning_error is not None and (self.bias.any() or self.start_offset.any()):
            raise ValueError("give either dead_reckoning_error or dr_bias_mps and start_offset_m, not both")
        self._scripted = dead_reckoning_error
        self.full_window = bool(full_window)
        self.skipped: Counter[str] = Counter()
        self.epoch_s: float | None = None  # the first ping's time: record times count from it
        self._interval: int | None = None  # the index of the interval being filled
        self._recent: deque[Ping] = deque()  # the pings of the last window_s, the interval's included
        # Per ping of _recent (which keeps it, so its id stays its own): its valid beams and its dead-reckoning error, each made once.
        self._held: dict[int, dict[str, object]] = {}
        self._heads: set[int] | None = None
        self._last: tuple[float, np.ndarray, np.ndarray] | None = None  # the last record: time, truth, dead reckoning
        self._first_s = 0.0  # the first record's time: a constant bias counts from it

    def add(self, ping: Ping) -> list[SurveyRecord]:
        """Take one ping; the records it closed (none, or one per interval it passed)."""
        if self.epoch_s is None:
            self.epoch_s = ping.time_s
        if self._heads is not None and ping.head not in self._heads:
            raise DifferentShipsError(
                f"a ping of sonar head or ship {ping.head} at {ping.time_s - self.epoch_s:.1f} s, after records of {sorted(self._heads)} only: "
                "files of different ships (or sonars) cannot make one survey's records; run each on its own")
        index = math.floor((ping.time_s - self.epoch_s) / self.interval_s)
        closed: list[SurveyRecord] = []
        if self._interval is not None and index > self._interval:
            closed += self._close()
        if self._last is not None and ping.time_s - self.epoch_s <= self._last[0]:
            self.skipped["ping earlier than a record already closed"] += 1
            return closed
        if self._interval is None:
            self._interval = index
        self._recent.append(ping)
        return closed

    def finish(self) -> list[SurveyRecord]:
        """Close the last interval."""
        return self._close() if self._interval is not None else []

    def _close(self) -> list[SurveyRecord]:
        self._interval = None
        last = max(self._recent, key=lambda p: p.time_s)
        # The "behind" rule's centre may be window_s back, and its pings window_s before that.
        oldest = last.time_s - (self.window_s if self.patch_rule == "window" else 2 * self.window_s + _TIME_TOLERANCE_S)
        while self._recent[0].time_s <= oldest:
            self._held.pop(id(self._recent.popleft()), None)
        pings = list(self._recent)
        if self._heads is None:
            self._heads = {p.head for p in pings}
        t = last.time_s - self.epoch_s
        truth = np.array([last.east_m, last.north_m])
        reckoned = truth + self._error(t)
        if self._last is None:
            velocity = np.full(2, np.nan)  # the first record starts the navigation; it moves nobody
            self._first_s = t
        else:
            t0, _, reckoned0 = self._last
            velocity = (reckoned - reckoned0) / (t - t0)
        self._last = (t, truth, reckoned)
        if self.full_window and t < self.window_s:
            self.skipped["record before its window of pings was full (kept without a patch)"] += 1
            patch, soundings = None, 0
        else:
            patch, soundings = self._patch(pings, last)
        nadir = _nadir_depth(last)
        vehicle_depth = last.origin_depth_m if math.isfinite(last.origin_depth_m) else 0.0
        return [SurveyRecord(t_s=t, ship_x_m=float(reckoned[0]), ship_y_m=float(reckoned[1]),
                             ship_heading_deg=(last.heading_deg + last.convergence_deg) % 360.0, vehicle_depth_m=vehicle_depth,
                             altitude_m=nadir - vehicle_depth, vel_x_mps=float(velocity[0]), vel_y_mps=float(velocity[1]),
                             truth_x_m=float(truth[0]), truth_y_m=float(truth[1]), sonar=patch, pings=len(pings), soundings=soundings)]

    def _patch(self, pings: list[Ping], last: Ping) -> tuple[SonarPatch | None, int]:
        moves = np.array([self._move(p, last) for p in pings])
        chosen, centre = self._behind(moves) if self.patch_rule == "behind" else (range(len(pings)), None)
        beams, kept = [], []
        for i in chosen:
            held = self._beams(pings[i])
            if held is not None:
                beams.append(held)
                kept.append(i)
        if not beams:
            self.skipped["record interval with no valid beam (kept without a patch)"] += 1
            return None, 0
        soundings = _WindowSoundings(tuple(beams), moves[kept])
        east, north, depth, age = soundings.arrays()
        if centre is None:
            centre = soundings_centre(east, north) if self.patch_centre == "soundings" else (0.0, 0.0)
        gridded = grid_soundings(east, north, depth, patch_shape=self.patch_shape, node_m=self.node_m, centre_m=centre, age_s=age,
                                 soundings=soundings)
        if gridded.outside:
            self.skipped["valid beams beyond the patch"] += gridded.outside
        if not gridded.used:
            self.skipped["record interval with no valid beam in the patch (kept without a patch)"] += 1
            return None, 0
        return gridded.patch, gridded.used

    def _move(self, ping: Ping, last: Ping) -> tuple[float, float, float]:
        """Where the navigation places ``ping`` from the record's vehicle (east, north: the true displacement plus the dead
        reckoning's error over its age, backwards), and its age."""
        drift = self._ping_error(ping) - self._ping_error(last)
        return ping.east_m - last.east_m + drift[0], ping.north_m - last.north_m + drift[1], last.time_s - ping.time_s

    def _ping_error(self, ping: Ping) -> np.ndarray:
        """The dead reckoning's error at ``ping``, made once for every record whose window holds it (the first record has closed:
        a constant bias counts from its time, which no longer moves)."""
        made = self._held.setdefault(id(ping), {})
        if "error" not in made:
            made["error"] = self._error(ping.time_s - self.epoch_s)
        return made["error"]

    def _behind(self, moves: np.ndarray) -> tuple[np.ndarray, tuple[float, float]]:
        """The "behind" rule (see the module): the pings (indices into ``moves``) of the patch, and its centre from the vehicle."""
        half_diagonal = math.hypot(*self.patch_shape) * self.node_m / 2
        age, reach = moves[:, 2], self.window_s + _TIME_TOLERANCE_S
        earlier = np.flatnonzero(age <= reach)
        behind = earlier[np.hypot(moves[earlier, 0], moves[earlier, 1]) >= half_diagonal]
        c = behind[np.argmin(age[behind])] if behind.size else earlier[np.argmax(age[earlier])]
        near = np.hypot(moves[:, 0] - moves[c, 0], moves[:, 1] - moves[c, 1]) <= half_diagonal
        return np.flatnonzero(near & (age <= age[c] + reach)), (float(moves[c, 0]), float(moves[c, 1]))

    def _beams(self, ping: Ping) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The ping's valid beams (east and north offsets from the ping, depth), made once and shared by every record whose
        window holds the ping; None without one."""
        made = self._held.setdefault(id(ping), {})
        if "beams" not in made:
            v = ping.valid & np.isfinite(ping.depth_m)
            made["beams"] = (ping.beam_east_m[v] - ping.east_m, ping.beam_north_m[v] - ping.north_m, ping.depth_m[v]) if v.any() else None
        return made["beams"]

    def _error(self, t: float) -> np.ndarray:
        """The dead-reckoned position less the truth at ``t`` seconds from the first ping."""
        if self._scripted is not None:
            return _pair(self._scripted(t), "dead_reckoning_error(t)")
        first = t if self._last is None else self._first_s
        return self.start_offset + self.bias * (t - first)


class _WindowSoundings:
    """A record's soundings (:class:`~lost.host.records.PatchSoundings`) as its pings' beams, shared with the records
    around it, and each ping's move to the record: the window's beams are held once, not once per record."""

    def __init__(self, beams: tuple, moves: np.ndarray) -> None:
        self._beams, self._moves = beams, moves  # moves: (pings, 3) east and north of the ping from the record, its age

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        counts = [b[2].size for b in self._beams]
        east = np.concatenate([b[0] for b in self._beams]) + np.repeat(self._moves[:, 0], counts)
        north = np.concatenate([b[1] for b in self._beams]) + np.repeat(self._moves[:, 1], counts)
        return east, north, np.concatenate([b[2] for b in self._beams]), np.repeat(self._moves[:, 2], counts)


def _nadir_depth(ping: Ping) -> float:
    """The depth of the valid beam nearest the ping's nadir (NaN without one): the record's ocean depth."""
    v = ping.valid & np.isfinite(ping.depth_m)
    if not v.any():
        return math.nan
    k = int(np.argmin(np.hypot(ping.along_m[v], ping.across_m[v])))
    return float(ping.depth_m[v][k])


def _pair(value, name: str) -> np.ndarray:
    pair = np.asarray(value, dtype=np.float64).ravel()
    if pair.size != 2 or not np.all(np.isfinite(pair)):
        raise ValueError(f"{name} must be two finite numbers (east, north), got {value!r}")
    return pair


def survey_records(survey: Survey, recorder: SurveyRecorder) -> NavRecords:
    """Every record of ``survey`` through ``recorder``, as :class:`~lost.host.records.NavRecords`.

    Raises
    ------
    NoPingsError
        The survey yields no ping with a position.
    DifferentShipsError
        A ping of a sonar head or ship the first record did not have.
    """
    rows: list[SurveyRecord] = []
    for ping in survey:
        rows += recorder.add(ping)
    rows += recorder.finish()
    if not rows:
        names = ", ".join(p.name for p in survey.paths)
        raise NoPingsError(f"{names}: no ping with a position to make records of (skipped: {dict(survey.skipped) or 'nothing'})")
    return nav_records(rows)


def nav_records(rows: list[SurveyRecord]) -> NavRecords:
    """Survey records as :class:`~lost.host.records.NavRecords` (no cable, no slant range: a hull-mounted sonar)."""
    column = {name: np.array([getattr(r, name) for r in rows], dtype=np.float64)
              for name in ("t_s", "ship_x_m", "ship_y_m", "ship_heading_deg", "vehicle_depth_m", "altitude_m", "vel_x_mps", "vel_y_mps",
                           "truth_x_m", "truth_y_m")}
    n = len(rows)
    return NavRecords(**column, slant_range_m=np.full(n, np.nan), cable_out_m=np.zeros(n), sonar=tuple(r.sonar for r in rows))


def check_survey_on_map(records: NavRecords, grid, names: str) -> list[str]:
    """Refuse a survey whose track misses the map (:class:`SurveyOffMapError`); warnings for a track partly off it.

    The track is the file's positions (the truth): the navigation needs the map where the ship sailed, not
    where its dead reckoning wanders.
    """
    inside = grid.contains(records.truth_x_m, records.truth_y_m)
    if not inside.any():
        rows, cols = grid.shape
        raise SurveyOffMapError(
            f"{names}: no position of the survey's track lies on the map: the track spans east {np.min(records.truth_x_m):.0f} to "
            f"{np.max(records.truth_x_m):.0f} m, north {np.min(records.truth_y_m):.0f} to {np.max(records.truth_y_m):.0f} m, the map east "
            f"{grid.x0_m:.0f} to {grid.x0_m + (cols - 1) * grid.node_m:.0f} m, north {grid.y0_m:.0f} to {grid.y0_m + (rows - 1) * grid.node_m:.0f} m "
            f"(CRS {grid.crs}); give the map of this survey's area")
    if not inside.all():
        return [f"{int((~inside).sum())} of {inside.size} records of the survey lie off the map (the first at {float(records.t_s[~inside][0]):.1f} s)"]
    return []
