"""The return to the map: refusals of a density that dead reckoning alone has shaped re-initialize nothing."""

import numpy as np

from lost.host.grid import Grid
from lost.host.nav import NavParameters
from lost.host.nav.estimator import Motion, Observation
from lost.host.nav.likelihood import TerrainLikelihood
from lost.host.nav.mapprep import PreparedMap
from lost.host.nav.pmf import PointMassFilter
from lost.host.records import SonarPatch
from lost.host.terrain import synthetic_terrain

NODE = 10.0
HALF = 4  # 9 x 9 patches
TRUTH = np.array([600.0, 600.0])
DEAD_RECKONING_ERROR_M = np.array([100.0, 0.0])  # where the density comes back: 100 m east of the truth
GAP_S = 15  # records without a patch: beyond off_map_usable_s (10 s)


def _observation(patch=None):
    return Observation(t_s=0.0, frame=None, patch=patch, ocean_depth_m=np.nan, vehicle_depth_m=0.0, slant_range_m=np.nan)


def _filter():
    floor = synthetic_terrain((120, 120), seed=4, roughness_m=10.0, hurst=0.5)
    grid = Grid(floor, 0.0, 0.0, NODE)
    # The density's variance grows by 25 m**2 a record. Dead reckoning takes it 100 m east of the truth: its NIS against
    # the 100 m correction, about 100**2 / sigma**2, is beyond the gate (13.8) until sigma passes 27 m; its grid spans
    # 8 sigma so that the truth lies on it. Without a lay-back a re-initialization is flat over 8 initial sigmas (80 m)
    # around the estimate, which do not reach the truth.
    params = NavParameters(velocity_noise_mps=5.0, gyro_bias_rps=0.0, accel_bias_mps2=0.0, use_slant_range=False, estimate_velocity_bias=False,
                           initial_sigma_m=10.0, pmf_sigmas=8.0, reinit_after=2, temper_by_correlation=False)
    likelihood = TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0)
    f = PointMassFilter(likelihood, params, grid=grid)
    f.start(0.0, TRUTH, _observation())
    row, col = (int(v / NODE) for v in TRUTH[::-1])
    patch = SonarPatch(floor[row - HALF : row + HALF + 1, col - HALF : col + HALF + 1] + 2.0, NODE)
    for _ in range(3):  # the density takes the terrain at the truth
        _step(f, patch)
    assert f.counts["terrain_updates"] == 3
    return f, patch


def _step(f, patch=None, velocity_mps=(0.0, 0.0)):
    f.predict(Motion(dt_s=1.0, velocity_mps=np.asarray(velocity_mps, float)))
    f.update(_observation(patch))


def test_a_density_back_from_a_gap_widens_until_it_takes_the_terrains_correction():
    f, patch = _filter()
    for _ in range(GAP_S):  # no patch, and a velocity error that takes the density 100 m east
        _step(f, velocity_mps=DEAD_RECKONING_ERROR_M / GAP_S)
    for _ in range(30):
        _step(f, patch)
    assert f.counts["refused_on_return"] >= 2 and f.counts["reinitializations"] == 0
    assert f.counts["returned_after_refusals"] == 1 and f.counts["terrain_updates"] > 3
    assert np.hypot(*(f.estimate().position - TRUTH)) < 5.0


def test_refusals_without_a_gap_before_them_still_re_initialize():
    f, patch = _filter()
    _step(f, patch, velocity_mps=DEAD_RECKONING_ERROR_M)  # a dead-reckoning jump of 100 m between two patches
    _step(f, patch)
    assert f.counts["refused_on_return"] == 0 and f.counts["reinitializations"] == 1
    assert f.estimate().reinitialized == "updates_refused"
