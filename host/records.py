"""The sensor records of one tow: what the navigation pipeline consumes.

Both the navigation-log reader (recorded surveys) and the scenario simulator (synthetic tows)
produce a :class:`NavRecords`, so the pipeline never knows which it was given. All positions are in
the projected metric frame of the :class:`~lost.host.grid.Grid` (easting x, northing y); a missing
reading is NaN, never a made-up value.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

__all__ = ["NavRecords", "SonarPatch"]


@dataclass(frozen=True)
class SonarPatch:
    """Gridded sonar soundings near the vehicle at one record.

    ``depth_m[k, l]`` is the sea-floor depth (metres, positive down, NaN where no beam landed) at
    northing offset ``(k - (h - 1) / 2) * node_m`` and easting offset ``(l - (w - 1) / 2) * node_m``
    from the patch centre, in the grid's axes (row grows north, column east), so it can be
    correlated directly against the map. The centre lies ``centre_offset_m`` (east, north) from the
    vehicle's position at the record: (0, 0) for a patch around the vehicle; behind it for a patch
    built in real time from the pings already received.
    """

    depth_m: np.ndarray
    node_m: float
    centre_offset_m: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        offset = tuple(float(v) for v in np.asarray(self.centre_offset_m, dtype=np.float64).ravel())
        if len(offset) != 2 or not all(np.isfinite(offset)):
            raise ValueError(f"centre_offset_m must be two finite numbers (east, north) in metres, got {self.centre_offset_m!r}")
        object.__setattr__(self, "centre_offset_m", offset)


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

    def __len__(self) -> int:
        return len(self.t_s)

    @property
    def has_truth(self) -> bool:
        return self.truth_x_m is not None
