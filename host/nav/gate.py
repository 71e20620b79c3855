"""A measurement gate scaled by what the measurements show: the stated variance is a worst case.

A slant range's or a USBL fix's innovation is gated by its normalized square, ``nu^T (H P H^T + R)^-1 nu``, against
chi-square. The stated variance is the worst case (the density carries its floor; a range sigma its worst geometry; a
fix's covariance the device's own figure), and real measurements agree with a settled density far better than that.
There an outlier of the measurement's own size passes a gate set for the stated variance and takes a narrow density
with it for a record. The median of the last ``memory`` normalized innovations (refused ones too, so that the scale does
not feed on its own gate; a median, so that the outliers themselves hardly move it) over chi-square's median is how far
the stated variance overstates the real one; the gate is scaled by it, between ``least`` and 1 (never looser than
stated). Until ``memory`` values are in, 1.
"""

from __future__ import annotations

import math
import statistics
from collections import deque

__all__ = ["LearnedGate", "CHI2_1_MEDIAN", "CHI2_2_MEDIAN", "GATE_MEMORY", "GATE_SCALE_MIN"]

#: The median of chi-square with one degree of freedom (a range's normalized innovation squared).
CHI2_1_MEDIAN = 0.454936
#: The median of chi-square with two degrees of freedom, 2 ln 2 (a position fix's).
CHI2_2_MEDIAN = 2.0 * math.log(2.0)
#: Innovations whose median sets a gate's scale.
GATE_MEMORY = 50
#: The least learned scale of a gate.
GATE_SCALE_MIN = 0.2


class LearnedGate:
    """The running scale of a gate on normalized innovations whose consistent median is ``chi2_median``."""

    def __init__(self, chi2_median: float, memory: int = GATE_MEMORY, least: float = GATE_SCALE_MIN) -> None:
        self._median = float(chi2_median)
        self._least = float(least)
        self._values: deque[float] = deque(maxlen=int(memory))
        self.scale = 1.0

    def note(self, value: float) -> float:
        """A normalized innovation squared joins the window; the gate's scale (1 until the window is full)."""
        if math.isfinite(value):
            self._values.append(value)
            if len(self._values) == self._values.maxlen:
                self.scale = min(max(statistics.median(self._values) / self._median, self._least), 1.0)
        return self.scale
