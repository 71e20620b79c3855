"""The records of one simulated tow read from two formats, compared to the formats' precision (shared by the export tests)."""

from __future__ import annotations

import numpy as np


def assert_records_agree(a, b, count: int) -> None:
    """``count`` records each; times, tracks and headings to the coarser format's precision; the patches the same depths, a
    node differing (its mean, or whether it has one) only where a rounding of a position moved a beam over a node's edge."""
    assert len(a.t_s) == len(b.t_s) == count
    np.testing.assert_allclose(b.t_s, a.t_s, atol=2e-3)  # .all keeps milliseconds
    for name in ("ship_x_m", "ship_y_m", "truth_x_m", "truth_y_m"):
        np.testing.assert_allclose(getattr(b, name), getattr(a, name), atol=0.02)  # .all: 1/20,000,000 degree of latitude
    np.testing.assert_allclose(b.ship_heading_deg, a.ship_heading_deg, atol=0.01)  # .all: 0.01 degree
    # .all's rounding of a position (5 mm of latitude, 1 cm of longitude, 0.01 degree of heading: 1.7 cm at 100 m across).
    nodes = moved = 0
    for pa, pb in zip(a.sonar, b.sonar, strict=True):
        assert (pa is None) == (pb is None)
        if pa is None:
            continue
        both = ~np.isnan(pa.depth_m) & ~np.isnan(pb.depth_m)
        difference = np.abs(pa.depth_m[both] - pb.depth_m[both])
        one_only = int((np.isnan(pa.depth_m) != np.isnan(pb.depth_m)).sum())
        nodes, moved = nodes + int(both.sum()) + one_only, moved + int((difference > 1e-3).sum()) + one_only
        assert np.max(difference, initial=0) < 1.0
    assert nodes > 1000 and moved / nodes < 0.02, (moved, nodes)
