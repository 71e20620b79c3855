"""Bounded statistics of a serving run: whatever the run's length, each store keeps a fixed number of values.

:class:`LogHistogram` counts values in logarithmic bins (``bins_per_decade`` per factor of ten between ``low``
and ``high``; values below ``low`` in the first bin, above ``high`` in the last); a quantile is read as the
upper edge of the bin that holds it, so it is never below the exact quantile and above it by at most one bin
(a factor of ``10 ** (1 / bins_per_decade)``: 1.2 % at 200 bins a decade), except beyond ``high`` where the
largest value seen is the answer. Count, sum of squares, the last value and the largest are kept exactly.

:class:`EstimatorStats` is one estimator's served records: how many, how many usable, and its horizontal error
against the pings' positions (the RMS exact, the 90th percentile from the histogram).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["LogHistogram", "EstimatorStats"]


class LogHistogram:
    """Streaming quantiles in a fixed-size logarithmic histogram (see the module)."""

    def __init__(self, *, low: float, high: float, bins_per_decade: int = 200) -> None:
        if not (0 < low < high and bins_per_decade > 0):
            raise ValueError(f"a log histogram needs 0 < low < high and bins_per_decade > 0, got {low}, {high}, {bins_per_decade}")
        self.low, self.high, self.bins_per_decade = float(low), float(high), int(bins_per_decade)
        self._bins = np.zeros(int(math.ceil(math.log10(high / low) * bins_per_decade)) + 1, dtype=np.int64)
        self.count = 0
        self.sum_squares = 0.0
        self.last = math.nan
        self.max = math.nan

    def add(self, value: float) -> None:
        """One value (a NaN or an infinity is not counted: the caller counts those apart)."""
        if not math.isfinite(value):
            return
        index = 0 if value <= self.low else min(int(math.log10(value / self.low) * self.bins_per_decade) + 1, self._bins.size - 1)
        self._bins[index] += 1
        self.count += 1
        self.sum_squares += value * value
        self.last = value
        self.max = value if not value <= self.max else self.max  # NaN at first: the first value

    def quantile(self, q: float) -> float:
        """The ``q`` quantile (0-1) of the values added, to one bin above (see the module); NaN when empty."""
        if not self.count:
            return math.nan
        rank = max(math.ceil(q * self.count), 1)
        index = int(np.searchsorted(np.cumsum(self._bins), rank))
        if index == self._bins.size - 1:
            return self.max
        return min(self.low * 10 ** (index / self.bins_per_decade), self.max)

    def rms(self) -> float:
        return math.sqrt(self.sum_squares / self.count) if self.count else math.nan


class EstimatorStats:
    """One estimator's served records: count, usable count, horizontal error's RMS and 90th percentile (bounded)."""

    def __init__(self) -> None:
        self.records = 0
        self.usable = 0
        self.error_m = LogHistogram(low=1e-3, high=1e6)

    def add(self, usable: bool, error_m: float) -> None:
        self.records += 1
        self.usable += bool(usable)
        self.error_m.add(error_m)

    @property
    def usable_fraction(self) -> float:
        return self.usable / self.records if self.records else math.nan

    def as_dict(self) -> dict:
        finite = self.error_m.count > 0
        return {"records": self.records, "usable_fraction": self.usable_fraction,
                "rms_m": self.error_m.rms() if finite else None, "p90_m": self.error_m.quantile(0.9) if finite else None}
