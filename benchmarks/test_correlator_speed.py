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
