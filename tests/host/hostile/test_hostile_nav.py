"""Hostile inputs of the navigation: a map that stops before the survey, implausible patch ages.

Each case is a tow simulated from a floor richer than the map the navigation gets (the floor goes on
where the map stops), and each asserts what a user would see: no fix off the map, the usable flag down,
counts that name what was skipped.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from lost.host.nav import NavParameters, navigate
from lost.host.scenario import load_scenario, simulate

EDGE_SCENARIO = """
name = "edge"
seed = 3
duration_s = 300
[terrain]
shape = [120, 220]
node_m = 10.0
roughness_m = 10.0
hurst = 0.5
[map]
extent_m = [0.0, 0.0, 400.0, 1200.0]   # the floor goes on east; the vehicle leaves the map after ~2 min
[ship]
waypoints_m = [[900.0, 600.0], [2100.0, 600.0]]
[cable]
out_m = 1200.0
"""


@pytest.fixture(scope="module")
def edge_run(tmp_path_factory):
    path = tmp_path_factory.mktemp("edge") / "edge.toml"
    path.write_text(EDGE_SCENARIO)
    grid, records = simulate(load_scenario(path))
    result = navigate(records, grid, NavParameters(search_half_width_m=100.0))
    truth = result.truth
    on_map = grid.contains(truth[:, 0], truth[:, 1])
    assert 60 < np.count_nonzero(~on_map) < 240, "the tow must leave the map part way"
    return grid, records, result, on_map


def test_the_patent_pipeline_takes_no_patch_fix_beyond_the_map_and_counts_off_map(edge_run):
    _, _, result, on_map = edge_run
    off = ~on_map
    assert np.count_nonzero((result.mle_source == "patch") & off) == 0
    assert result.counts["off_map"] >= 0.8 * np.count_nonzero(off)
    assert result.counts["patch_misfit"] > 0
    assert not result.tracks["lost"].usable[off][30:].any()


@pytest.mark.parametrize("name", ["pmf", "pf"])
def test_a_filter_beyond_the_map_is_not_usable_and_makes_no_false_fix(edge_run, name):
    _, _, result, on_map = edge_run
    track = result.tracks[name]
    error = np.hypot(*(track.position - result.truth).T)
    sigma = np.sqrt(np.linalg.eigvalsh(np.nan_to_num(track.covariance))[:, -1])
    off = np.flatnonzero(~on_map)
    # The grace after the last terrain update, then down for the rest of the tow.
    assert not track.usable[off[15:]].any()
    assert not np.any(track.usable & (error > 3.0 * sigma))


def test_implausible_patch_ages_are_skipped_and_counted_not_diffused(edge_run):
    grid, records, _, _ = edge_run
    n = 40
    sonar = [p if p is None or k % 2 else dataclasses.replace(p, age_s=1e7) for k, p in enumerate(records.sonar[:n])]
    fields = {f: getattr(records, f) for f in records.__dataclass_fields__}
    short = {k: (v[:n] if isinstance(v, np.ndarray) and v.shape[:1] == (len(records),) else v) for k, v in fields.items()}
    short["sonar"] = tuple(sonar)
    cut = type(records)(**short)
    result = navigate(cut, grid, NavParameters(search_half_width_m=100.0), estimators=("pmf",))
    aged = sum(1 for p in sonar if p is not None and p.age_s == 1e7)
    assert result.counts["patch_age_implausible"] == aged > 0
    assert np.isfinite(result.tracks["pmf"].position[1:]).all()


def test_a_diffusion_wider_than_the_grid_leaves_it_flat():
    from lost.host.grid import Grid
    from lost.host.nav.estimator import Motion, Observation
    from lost.host.nav.likelihood import TerrainLikelihood
    from lost.host.nav.mapprep import PreparedMap
    from lost.host.nav.pmf import PointMassFilter
    from lost.host.terrain import synthetic_terrain

    grid = Grid(synthetic_terrain((60, 60), seed=2, roughness_m=10.0, hurst=0.5), 0.0, 0.0, 10.0)
    pmf = PointMassFilter(TerrainLikelihood(PreparedMap(grid=grid), sigma_m=1.0), NavParameters(), grid=grid)
    pmf.start(0.0, np.array([300.0, 300.0]),
              Observation(t_s=0.0, frame=None, patch=None, ocean_depth_m=np.nan, vehicle_depth_m=0.0, slant_range_m=np.nan))
    pmf._pending_var = 1e14  # what an age of 1e7 s made of the misplacement variance
    pmf.predict(Motion(dt_s=1.0, velocity_mps=np.zeros(2)))
    _, _, p = pmf.density
    assert pmf.counts["diffusion_flattened"] == 1
    assert np.isfinite(p).all() and np.isclose(p.sum(), 1.0)


@pytest.mark.parametrize("field, value", [("off_map_usable_s", 0.0), ("max_patch_age_s", -1.0), ("max_patch_age_s", float("nan")),
                                          ("max_hole_share", 1.0), ("max_hole_share", -0.1), ("max_hole_share", float("nan")),
                                          ("drift_gate", 0.0), ("drift_gate", float("inf"))])
def test_the_new_bounds_are_validated(field, value):
    with pytest.raises(ValueError, match=field):
        NavParameters(**{field: value})


# ---- the map's own uncertainty -----------------------------------------------------------------------

def _small_grid():
    from lost.host.grid import Grid
    from lost.host.terrain import synthetic_terrain

    return Grid(synthetic_terrain((40, 50), seed=5, roughness_m=10.0, hurst=0.5), 0.0, 0.0, 10.0)


BAD_LAYERS = {
    "wrong_shape": (lambda d: np.ones((40, 49)), r"uncertainty layer is 40 x 49 nodes but its depth grid 40 x 50"),
    "one_dimensional": (lambda d: np.ones(2000), r"must be 2-D like its depth grid"),
    "negative": (lambda d: np.where(np.arange(d.size).reshape(d.shape) == 7, -0.3, 0.5),
                 r"1 negative standard deviation\(s\) \(first -0.3 m at row 0, column 7\)"),
    "nan_on_a_depth": (lambda d: np.where(np.arange(d.size).reshape(d.shape) == 60, np.nan, 0.5),
                       r"1 NaN or infinite value\(s\) on nodes with a depth \(first at row 1, column 10\)"),
    "text": (lambda d: np.full(d.shape, "0.5"), r"must hold numbers"),
}


@pytest.mark.parametrize("make, message", BAD_LAYERS.values(), ids=BAD_LAYERS.keys())
def test_a_bad_uncertainty_layer_is_refused_by_name(make, message):
    from lost.host.nav import PreparedMap

    grid = _small_grid()
    with pytest.raises(ValueError, match=message):
        PreparedMap(grid=grid, node_sigma_m=make(grid.depth_m))


def test_nan_sigma_on_a_hole_is_accepted():
    from lost.host.grid import Grid
    from lost.host.nav import PreparedMap

    grid = _small_grid()
    depth = grid.depth_m.copy()
    depth[3, 4] = np.nan
    sigma = np.full(depth.shape, 0.5)
    sigma[3, 4] = np.nan
    prepared = PreparedMap(grid=Grid(depth, 0.0, 0.0, 10.0), node_sigma_m=sigma)
    assert prepared.node_sigma_m[3, 4] == 0.0 and prepared.node_sigma_m[0, 0] == 0.5


def test_a_map_coarser_than_the_patches_is_named(edge_run):
    from lost.host.grid import Grid

    grid, records, _, _ = edge_run
    coarse = Grid(grid.depth_m[::3, ::3], grid.x0_m, grid.y0_m, 3 * grid.node_m)
    with pytest.raises(ValueError, match=r"the map's 30.0 m nodes are coarser than the sonar patches' 10.0 m.*block means of 3 x 3"):
        navigate(records, coarse, NavParameters())
