"""The serving run's bounded statistics: quantiles within one bin of NumPy's, a fixed size whatever the count."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lost.host.live.stats import EstimatorStats, LogHistogram


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_quantiles_are_at_or_above_the_exact_ones_by_at_most_one_bin(seed):
    rng = np.random.default_rng(seed)
    values = rng.lognormal(2.5, 1.0, 20_000)  # latencies, ms: a long tail
    histogram = LogHistogram(low=0.01, high=1e7)
    size = histogram._bins.nbytes
    for value in values:
        histogram.add(float(value))
    assert histogram._bins.nbytes == size and histogram.count == values.size
    step = 10 ** (1 / histogram.bins_per_decade)
    for q in (0.5, 0.9, 0.99, 1.0):
        exact = float(np.quantile(values, q, method="inverted_cdf"))
        assert exact <= histogram.quantile(q) <= exact * step * (1 + 1e-12), q
    assert histogram.max == values.max() and histogram.last == values[-1]
    assert histogram.rms() == pytest.approx(math.sqrt(np.mean(values**2)), rel=1e-9)


def test_out_of_range_values_land_in_the_end_bins_and_nan_is_not_counted():
    histogram = LogHistogram(low=1.0, high=100.0, bins_per_decade=10)
    for value in (0.0, 1e-9, 5.0, 1e9, math.nan, math.inf):
        histogram.add(value)
    assert histogram.count == 4
    assert histogram.quantile(0.5) == 1.0  # the two below low: the first bin's edge
    assert histogram.quantile(1.0) == 1e9  # above high: the largest value itself
    assert math.isnan(LogHistogram(low=1.0, high=2.0).quantile(0.5))
    with pytest.raises(ValueError, match="0 < low < high"):
        LogHistogram(low=2.0, high=1.0)


def test_an_estimators_stats_count_usable_and_errors_without_keeping_them():
    stats = EstimatorStats()
    for k in range(1000):
        stats.add(k % 4 != 0, float(k % 10) if k % 100 else math.nan)
    summary = stats.as_dict()
    assert summary["records"] == 1000 and summary["usable_fraction"] == 0.75
    errors = np.array([k % 10 for k in range(1000) if k % 100], dtype=float)
    assert summary["rms_m"] == pytest.approx(math.sqrt(np.mean(errors**2)))
    assert float(np.quantile(errors, 0.9, method="inverted_cdf")) <= summary["p90_m"] <= 9.0 * 1.012
