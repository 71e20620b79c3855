"""Floors as the sea has them: a shelf and its slope, canyons, ridges, seamounts, and a coarse grid refined below its node."""

import numpy as np
import pytest

from lost.host.terrain import Feature, feature_relief, node_scale_relief, refine, shelf_profile, synthetic_terrain


def test_a_shelf_deepens_by_its_gradient_then_by_the_slopes_beyond_the_break():
    # 4 km east at 10 m; the floor deepens eastward, the break 500 m east of the centre.
    profile = shelf_profile((5, 401), 10.0, gradient=0.005, downslope_deg=90.0, break_m=500.0, slope_gradient=0.08, break_width_m=100.0)
    row = profile[2]
    assert row[200] == pytest.approx(0.0, abs=0.01)  # zero at the centre, a shelf of 0.5 % around it
    assert np.diff(row[20:150]) == pytest.approx(0.05, abs=1e-4)
    assert np.diff(row[330:400]) == pytest.approx(0.8, rel=2e-3)  # 8 % beyond the break
    assert np.all(np.diff(row) > 0) and np.all(np.diff(row, 2) >= -1e-12)  # no kink: the gradient only grows
    np.testing.assert_allclose(profile[0], profile[4], atol=1e-9)  # nothing changes across the slope


def test_a_winding_canyon_cuts_its_depth_along_its_path_and_stays_near_it():
    canyon = Feature(kind="canyon", height_m=60.0, width_m=80.0, path_m=((500.0, 2000.0), (4500.0, 2000.0)), meander_m=200.0,
                     meander_wavelength_m=1500.0)
    cut = feature_relief((400, 500), 10.0, [canyon], seed=4)
    inner = cut[:, 100:400]
    deepest_row = inner.argmax(axis=0)
    assert inner.max(axis=0) == pytest.approx(60.0, abs=1.0)  # its full depth somewhere across every column
    # It winds: its axis moves by more than a width, but no farther than a few meander amplitudes from the path.
    offset = deepest_row * 10.0 - 2000.0
    assert np.ptp(offset) > 160.0 and np.max(np.abs(offset)) < 4 * 200.0
    assert np.abs(cut[:50]).max() < 1e-6  # far away nothing
    # Steep walls round a flat floor: height / (1 + (d / width)**4), here on a straight canyon.
    straight = feature_relief((400, 500), 10.0, [Feature(kind="canyon", height_m=60.0, width_m=80.0, path_m=canyon.path_m)], seed=4)
    assert straight[200, 250] == pytest.approx(60.0) and straight[204, 250] == pytest.approx(60.0 / (1 + 0.5**4))
    assert straight[208, 250] == pytest.approx(30.0) and straight[216, 250] == pytest.approx(60.0 / 17)
    # Seeded: the same seed, the same canyon; another seed winds otherwise.
    np.testing.assert_array_equal(cut, feature_relief((400, 500), 10.0, [canyon], seed=4))
    assert not np.array_equal(cut, feature_relief((400, 500), 10.0, [canyon], seed=5))


def test_a_ridge_and_a_seamount_raise_the_floor_where_they_are():
    ridge = Feature(kind="ridge", height_m=40.0, width_m=100.0, path_m=((1000.0, 1000.0), (3000.0, 1000.0)))
    seamount = Feature(kind="seamount", height_m=150.0, width_m=400.0, at_m=(3500.0, 3000.0))
    relief = feature_relief((400, 500), 10.0, [ridge, seamount], seed=0)
    assert relief[100, 200] == pytest.approx(-40.0, abs=0.5)  # on the ridge's crest (depth decreases)
    assert relief[110, 200] == pytest.approx(-40.0 * np.exp(-1.0), abs=0.5)  # one width off: 1/e
    assert relief[300, 350] == pytest.approx(-150.0, abs=0.1)
    assert relief[300, 390] == pytest.approx(-150.0 * np.exp(-1.0), abs=0.5)


@pytest.mark.parametrize("bad, message", [
    (dict(kind="trench", height_m=1.0, width_m=1.0, path_m=((0, 0), (1, 1))), "kind"),
    (dict(kind="seamount", height_m=1.0, width_m=1.0), "at_m"),
    (dict(kind="canyon", height_m=1.0, width_m=1.0, path_m=((0.0, 0.0),)), "path_m"),
    (dict(kind="ridge", height_m=1.0, width_m=0.0, path_m=((0, 0), (1, 1))), "width_m"),
])
def test_a_feature_missing_what_it_needs_is_named(bad, message):
    with pytest.raises(ValueError, match=message):
        Feature(**bad)


def test_a_refined_grid_keeps_the_coarse_depths_and_adds_detail_below_the_node_only():
    coarse = synthetic_terrain((120, 150), seed=3, relief_m=30.0, roughness_m=5.0, hurst=0.8)
    fine = refine(coarse, 5, seed=1, detail_m=1.0)
    assert fine.shape == (596, 746)
    assert np.std(fine - refine(coarse, 5, seed=1, detail_m=0.0)) == pytest.approx(1.0, rel=0.05)
    # Means over a coarse cell keep the coarse depth: the detail has no wavelength longer than two coarse nodes.
    cells = fine[:595, :745].reshape(119, 5, 149, 5).mean(axis=(1, 3))
    centres = (coarse[:-1, :-1] + coarse[1:, 1:] + coarse[1:, :-1] + coarse[:-1, 1:]) / 4
    assert np.std(cells - centres) < 0.35
    # Without detail_m the coarse grid's own relief at its node sets it.
    estimated = refine(coarse, 5, seed=1)
    assert np.std(estimated - refine(coarse, 5, seed=1, detail_m=0.0)) == pytest.approx(node_scale_relief(coarse), rel=0.05)
    assert node_scale_relief(np.add.outer(np.arange(50.0), np.arange(60.0))) == pytest.approx(0.0, abs=1e-9)  # a plane has none
    np.testing.assert_array_equal(refine(coarse, 1, seed=1), coarse)


def test_a_refined_grid_keeps_its_holes():
    coarse = synthetic_terrain((60, 60), seed=3)
    coarse[20:24, 30:35] = np.nan
    fine = refine(coarse, 4, seed=2)
    assert np.isnan(fine[84:89, 124:133]).all()  # the hole, four times finer
    assert np.isfinite(fine[:70]).all() and np.isfinite(fine[100:]).all()  # and nothing else
