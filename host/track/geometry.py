"""The sonar's sector and the one conversion between its polar frame and the world.

World frame: east ``x``, north ``y``, metres. A sonar sits at the platform's GPS position and looks
along the platform's heading (degrees clockwise from north). A contact is at range ``r`` (metres)
and bearing ``b`` (degrees from the sonar's axis, positive to starboard, i.e. clockwise), so its
world position is ``(x, y) + r (sin(h + b), cos(h + b))``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Sonar", "polar_to_world", "world_to_polar", "wrap_deg"]


@dataclass(frozen=True, kw_only=True)
class Sonar:
    """The sector an active sonar covers and how often it pings (Guilmain & Sharma, section 2).

    Parameters
    ----------
    max_range_m : float
        Detections reach this far (paper: 500 m).
    half_fov_deg : float
        Half the horizontal field of view either side of the axis (paper: 45 degrees).
    ping_interval_s : float
        Time between pings (paper: 1.3 s).
    """

    max_range_m: float = 500.0
    half_fov_deg: float = 45.0
    ping_interval_s: float = 1.3

    def __post_init__(self) -> None:
        if not (self.max_range_m > 0 and 0 < self.half_fov_deg <= 180 and self.ping_interval_s > 0):
            raise ValueError(
                f"A sonar needs a positive range, a half field of view in (0, 180] degrees and a positive ping interval, "
                f"got {self.max_range_m!r} m, {self.half_fov_deg!r} deg, {self.ping_interval_s!r} s."
            )

    @property
    def area_m2(self) -> float:
        """Area of the sector, square metres."""
        return float(np.radians(self.half_fov_deg) * self.max_range_m**2)

    @property
    def polar_extent(self) -> float:
        """Size of the sector in range-bearing space, metres times radians (the clutter density's unit)."""
        return float(self.max_range_m * 2 * np.radians(self.half_fov_deg))

    def inside(self, range_m: np.ndarray, bearing_deg: np.ndarray) -> np.ndarray:
        """Whether each (range, bearing) lies in the sector."""
        return (range_m >= 0) & (range_m <= self.max_range_m) & (np.abs(bearing_deg) <= self.half_fov_deg)


def wrap_deg(angle_deg: np.ndarray | float) -> np.ndarray:
    """Angles folded into [-180, 180) degrees."""
    return (np.asarray(angle_deg) + 180.0) % 360.0 - 180.0


def polar_to_world(platform_xy: np.ndarray, heading_deg: float, range_m: np.ndarray, bearing_deg: np.ndarray) -> np.ndarray:
    """World positions, shape (n, 2), of contacts at ``range_m``, ``bearing_deg`` from a sonar at ``platform_xy``."""
    azimuth = np.radians(heading_deg + np.asarray(bearing_deg, dtype=float))
    range_m = np.asarray(range_m, dtype=float)
    return np.column_stack((platform_xy[0] + range_m * np.sin(azimuth), platform_xy[1] + range_m * np.cos(azimuth)))


def world_to_polar(platform_xy: np.ndarray, heading_deg: float, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Range (metres) and bearing (degrees from the axis, in [-180, 180)) of world positions ``xy`` (n, 2)."""
    dx = xy[:, 0] - platform_xy[0]
    dy = xy[:, 1] - platform_xy[1]
    return np.hypot(dx, dy), wrap_deg(np.degrees(np.arctan2(dx, dy)) - heading_deg)
