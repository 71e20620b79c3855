"""Correlator speed on the paper's sizes: 501 x 501 map, 10 x 10 patch, mean-compensated.

Run with `make bench`. The software backend is the figure the README quotes; the golden model and
OpenCV's float matchTemplate (not exact) are the yardsticks.
"""

import cv2
import numpy as np
import pytest

from lost import model
from lost.host import correlate
from lost.host.terrain import synthetic_terrain


@pytest.fixture(scope="module")
def paper_case():
    terrain = model.quantize(synthetic_terrain((501, 501), seed=1), 0.1, offset_m=1000.0)
    patch = terrain[200:210, 300:310].copy()
    return terrain, patch


@pytest.mark.parametrize("backend", ["software", "model"])
def test_correlate_501_10(benchmark, paper_case, backend):
    terrain, patch = paper_case
    surface = benchmark(correlate, terrain, patch, backend=backend)
    assert model.best_fit(surface).best == model.Placement(200, 300, 0)


def test_opencv_matchtemplate_sqdiff_float32_501_10(benchmark, paper_case):
    terrain, patch = (a.astype(np.float32) for a in paper_case)
    surface = benchmark(cv2.matchTemplate, terrain, patch, cv2.TM_SQDIFF)
    assert np.unravel_index(np.argmin(surface), surface.shape) == (200, 300)


@pytest.mark.parametrize("side", [501, 4000])
def test_correlation_of_a_filters_search_area_on_a_map_with_holes(benchmark, side):
    """A filter's update: 60 x 60 placements of a large survey grid with holes (real grids have them).

    The hole policy once built a prefix sum of the whole map at every call: 380 ms at 4000 x 4000.
    """
    from lost.host.correlator import correlation

    rng = np.random.default_rng(side)
    terrain = rng.integers(-1000, 1000, (side, side)).astype(np.int16)
    holes = np.zeros((side, side), bool)
    holes[rng.integers(0, side, 50), rng.integers(0, side, 50)] = True
    i0 = j0 = side // 2
    patch = terrain[i0 + 20 : i0 + 30, j0 + 20 : j0 + 30].copy()
    result = benchmark(correlation, terrain, patch, area=(i0, j0, 60, 60), holes=holes)
    assert result.best.value == 0 or holes[i0 + 20 : i0 + 30, j0 + 20 : j0 + 30].any()
