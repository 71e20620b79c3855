"""The one shape both trackers' outputs take for scoring and plotting: per ping, the reported contacts."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Estimate"]


@dataclass(frozen=True)
class Estimate:
    """A contact a tracker reports at one ping: its identity, position (m) and velocity (m/s), world east/north."""

    track_id: int
    x_m: float
    y_m: float
    vx_mps: float
    vy_mps: float

    @property
    def xy(self) -> np.ndarray:
        return np.array([self.x_m, self.y_m])
