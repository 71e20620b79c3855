"""The sensor records of one tow: what the navigation pipeline consumes.

Both the navigation-log reader (recorded surveys) and the scenario simulator (synthetic tows)
produce a :class:`NavRecords`, so the pipeline never knows which it was given. All positions are in
the projected metric frame of the :class:`~lost.host.grid.Grid` (easting x, northing y); a missing
reading is NaN, never a made-up value.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Protocol

import numpy as np

__all__ = ["NavRecords", "PatchSoundings", "SonarPatch", "SoundingArrays", "USBL_FIELDS"]


class PatchSoundings(Protocol):
    """The soundings a patch was gridded from, so that it can be gridded again with each placed otherwise."""

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Each sounding's (east, north) offset from the vehicle at the record as reckoned (metres), its depth
        (metres, positive down) and its age (seconds before the record)."""
        ...


@dataclass(frozen=True)
class SoundingArrays:
    """:class:`PatchSoundings` held as four arrays of one length."""

    east_m: np.ndarray
    north_m: np.ndarray
    depth_m: np.ndarray
    age_s: np.ndarray

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.east_m, self.north_m, self.depth_m, self.age_s


@dataclass(frozen=True)
class SonarPatch:
    """Gridded sonar soundings near the vehicle at one record.

    ``depth_m[k, l]`` is the sea-floor depth (metres, positive down, NaN where no beam landed) at
    northing offset ``(k - (h - 1) / 2) * node_m`` and easting offset ``(l - (w - 1) / 2) * node_m``
    from the patch centre, in the grid's axes (row grows north, column east), so it can be
    correlated directly against the map. The centre lies ``centre_offset_m`` (east, north) from the
    vehicle's position at the record: (0, 0) for a patch around the vehicle; behind it for a patch
    built in real time from the pings already received. ``age_s`` is how long before the record its
    soundings were taken, on average: their offsets were reckoned back over that time with the measured
    velocity, so a velocity bias b misplaces the patch by b times its age (0 for a snapshot; negative
    for a post-processed patch of soundings taken after the record). ``soundings``, when the patch was gridded
    from pings, are those pings' soundings: the navigation grids them again with each placed by its own age
    (:mod:`lost.host.nav.motion`); a patch without them (a snapshot, a patch read from a file) is used as it is.
    """

    depth_m: np.ndarray
    node_m: float
    centre_offset_m: tuple[float, float] = (0.0, 0.0)
    age_s: float = 0.0
    soundings: PatchSoundings | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        offset = tuple(float(v) for v in np.asarray(self.centre_offset_m, dtype=np.float64).ravel())
        if len(offset) != 2 or not all(np.isfinite(offset)):
            raise ValueError(f"centre_offset_m must be two finite numbers (east, north) in metres, got {self.centre_offset_m!r}")
        object.__setattr__(self, "centre_offset_m", offset)
        if not np.isfinite(self.age_s):
            raise ValueError(f"age_s must be a finite number of seconds, got {self.age_s!r}")
        object.__setattr__(self, "age_s", float(self.age_s))


@dataclass(frozen=True)
class NavRecords:
    """Time series of one tow, one entry per record, all of length N.

    Attributes
    ----------
    t_s : seconds, strictly increasing.
    ship_x_m, ship_y_m : the ship's GPS position (easting, northing), metres.
    ship_heading_deg : the ship's heading, degrees clockwise from grid north.
    vehicle_depth_m : the vehicle's pressure depth below the surface, metres.
    altitude_m : the vehicle's altimeter height above the sea floor, metres.
    vel_x_mps, vel_y_mps : the vehicle's velocity over ground (INS/DVL), or the ship's when the vehicle
        has none; metres per second.
    slant_range_m : ship (reference point) to vehicle, metres; NaN when not measured.
    cable_out_m : cable paid out, metres; drives the lay-back model.
    sonar : one :class:`SonarPatch` (or None) per record; empty when the tow has no swath sonar.
    truth_x_m, truth_y_m : the vehicle's true position when known (simulations), else None.
    usbl_travel_time_s : one-way acoustic travel time from the ship's USBL transducer to the vehicle's
        transponder, seconds; NaN when no reply (the navigation ray-traces it into a slant range).
    usbl_x_m, usbl_y_m : the USBL fix of the vehicle (easting, northing), metres; NaN without one.
    usbl_sxx, usbl_syy, usbl_sxy : the fix's covariance (east variance, north variance, their
        covariance), m**2; a fix comes with all five values or none.
    The six USBL series are optional: None (the default) means no USBL, stored as NaN.
    """

    t_s: np.ndarray
    ship_x_m: np.ndarray
    ship_y_m: np.ndarray
    ship_heading_deg: np.ndarray
    vehicle_depth_m: np.ndarray
    altitude_m: np.ndarray
    vel_x_mps: np.ndarray
    vel_y_mps: np.ndarray
    slant_range_m: np.ndarray
    cable_out_m: np.ndarray
    sonar: tuple[SonarPatch | None, ...] = field(default_factory=tuple)
    truth_x_m: np.ndarray | None = None
    truth_y_m: np.ndarray | None = None
    usbl_travel_time_s: np.ndarray | None = None
    usbl_x_m: np.ndarray | None = None
    usbl_y_m: np.ndarray | None = None
    usbl_sxx: np.ndarray | None = None
    usbl_syy: np.ndarray | None = None
    usbl_sxy: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = len(np.asarray(self.t_s))
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "sonar":
                if len(value) not in (0, n):
                    raise ValueError(f"sonar has {len(value)} entries for {n} records")
                object.__setattr__(self, "sonar", tuple(value))
                continue
            if value is None:
                if f.name in ("truth_x_m", "truth_y_m"):
                    continue
                if f.name in USBL_FIELDS:
                    value = np.full(n, np.nan)
                else:
                    raise ValueError(f"{f.name} is missing")
            array = np.asarray(value, dtype=np.float64)
            if array.shape != (n,):
                raise ValueError(f"{f.name} has shape {array.shape}, expected ({n},) like t_s")
            object.__setattr__(self, f.name, array)
        if (self.truth_x_m is None) != (self.truth_y_m is None):
            raise ValueError("truth_x_m and truth_y_m go together")
        if n and not np.all(np.isfinite(self.t_s)):
            raise ValueError("t_s has NaN or infinite times")
        backwards = np.flatnonzero(np.diff(self.t_s) <= 0)
        if backwards.size:
            k = int(backwards[0])
            raise ValueError(
                f"time does not increase at record {k + 1}: t={float(self.t_s[k + 1])} s after {float(self.t_s[k])} s "
                f"({backwards.size} such record(s))"
            )

        _check_usbl(self)

    def __len__(self) -> int:
        return len(self.t_s)

    @property
    def has_truth(self) -> bool:
        return self.truth_x_m is not None

    @property
    def has_usbl(self) -> bool:
        """Whether any record has a USBL travel time or fix."""
        return bool(np.isfinite(self.usbl_travel_time_s).any() or np.isfinite(self.usbl_x_m).any())

    def usbl_fix(self, n: int) -> tuple[np.ndarray, np.ndarray] | None:
        """The USBL fix of record ``n``: (east, north) and its 2 x 2 covariance, or None."""
        if not np.isfinite(self.usbl_x_m[n]):
            return None
        sxy = self.usbl_sxy[n]
        return (np.array([self.usbl_x_m[n], self.usbl_y_m[n]]), np.array([[self.usbl_sxx[n], sxy], [sxy, self.usbl_syy[n]]]))


#: The optional USBL series of :class:`NavRecords`; the fix is the last five, all or none per record.
USBL_FIELDS = ("usbl_travel_time_s", "usbl_x_m", "usbl_y_m", "usbl_sxx", "usbl_syy", "usbl_sxy")


def _check_usbl(records: NavRecords) -> None:
    """Refuse a travel time that is no time and a fix that is partial or whose covariance is no covariance."""
    travel = records.usbl_travel_time_s
    bad = np.flatnonzero(np.isfinite(travel) & ~(travel > 0)) if travel.size else np.array([], int)
    if bad.size:
        raise ValueError(f"usbl_travel_time_s must be positive seconds, got {float(travel[bad[0]])!r} at record {int(bad[0])}")
    x, y, sxx, syy, sxy = (getattr(records, name) for name in USBL_FIELDS[1:])
    given = np.isfinite(np.stack([x, y, sxx, syy, sxy]))
    partial = np.flatnonzero(given.any(axis=0) & ~given.all(axis=0))
    if partial.size:
        k = int(partial[0])
        missing = [name for name, ok in zip(USBL_FIELDS[1:], given[:, k]) if not ok]
        raise ValueError(f"the USBL fix of record {k} lacks {', '.join(missing)}: a fix needs usbl_x_m, usbl_y_m, usbl_sxx, usbl_syy, "
                         f"usbl_sxy together ({partial.size} such record(s))")
    with np.errstate(invalid="ignore"):
        not_covariance = given.all(axis=0) & ~((sxx > 0) & (syy > 0) & (sxy * sxy < sxx * syy))
    if not_covariance.any():
        k = int(np.flatnonzero(not_covariance)[0])
        raise ValueError(f"the USBL fix of record {k} has no covariance: usbl_sxx={sxx[k]:g}, usbl_syy={syy[k]:g}, usbl_sxy={sxy[k]:g} "
                         "must be variances (m**2, positive) with usbl_sxy**2 < usbl_sxx * usbl_syy")
