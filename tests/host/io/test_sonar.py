"""Sonar soundings to a vehicle-centred patch: node placement, means, holes and the count of the rest."""

import numpy as np
import pytest

from lost.host.io.sonar import grid_soundings, soundings_centre


def test_each_sounding_lands_on_its_node():
    # A 3 x 5 patch at 2 m: node (k, l) sits at north (k - 1) * 2, east (l - 2) * 2.
    north = np.array([-2.0, 0.0, 2.0, 0.4, -0.9])
    east = np.array([-4.0, 0.0, 4.0, 2.2, -3.1])
    depth = np.array([10.0, 11.0, 12.0, 13.0, 14.0])
    out = grid_soundings(east, north, depth, patch_shape=(3, 5), node_m=2.0)
    expected = np.full((3, 5), np.nan)
    expected[0, 0], expected[1, 2], expected[2, 4], expected[1, 3], expected[1, 0] = 10, 11, 12, 13, 14
    np.testing.assert_array_equal(out.patch.depth_m, expected)
    assert out.patch.node_m == 2.0 and (out.used, out.outside) == (5, 0)


def test_node_depth_is_the_mean_of_its_soundings():
    out = grid_soundings([0.1, -0.2, 0.3], [0.0, 0.1, -0.3], [10.0, 20.0, 60.0], patch_shape=(1, 1), node_m=1.0)
    assert out.patch.depth_m[0, 0] == 30.0 and out.used == 3


def test_even_patch_centre_and_half_node_ties():
    # A 2 x 2 patch at 1 m has nodes at offsets -0.5 and +0.5; the vehicle itself is a tie, going up.
    out = grid_soundings([0.0, -0.5], [0.0, -0.5], [5.0, 7.0], patch_shape=(2, 2), node_m=1.0)
    np.testing.assert_array_equal(out.patch.depth_m, [[7.0, np.nan], [np.nan, 5.0]])


def test_soundings_beyond_the_patch_are_counted_not_used():
    out = grid_soundings([0.0, 5.01, -5.0, 0.0], [0.0, 0.0, 0.0, 5.2], [1.0, 2.0, 3.0, 4.0], patch_shape=(10, 10), node_m=1.0)
    # East -5.0 is node -0.5 away from column 0 (-4.5): a tie going up, so it lands on column 0.
    assert (out.used, out.outside) == (2, 2)
    assert np.nansum(out.patch.depth_m) == 4.0 and np.isfinite(out.patch.depth_m).sum() == 2


def test_no_soundings_is_an_all_nan_patch():
    out = grid_soundings([], [], [], patch_shape=(4, 4), node_m=1.0)
    assert np.all(np.isnan(out.patch.depth_m)) and (out.used, out.outside) == (0, 0)


@pytest.mark.parametrize(
    "args, kwargs, message",
    [
        (([0.0], [0.0], [np.nan]), dict(patch_shape=(2, 2), node_m=1.0), "finite"),
        (([0.0, 1.0], [0.0], [1.0]), dict(patch_shape=(2, 2), node_m=1.0), "have 2, 1 and 1"),
        (([0.0], [0.0], [1.0]), dict(patch_shape=(0, 2), node_m=1.0), "patch_shape"),
        (([0.0], [0.0], [1.0]), dict(patch_shape=(2.5, 2), node_m=1.0), "patch_shape"),
        (([0.0], [0.0], [1.0]), dict(patch_shape=(2, 2), node_m=0.0), "node_m"),
        (([0.0], [0.0], [1.0]), dict(patch_shape=(2, 2), node_m=1.0, centre_m=(0.0, np.nan)), "centre_m"),
        (([0.0], [0.0], [1.0]), dict(patch_shape=(2, 2), node_m=1.0, centre_m=(1.0,)), "centre_m"),
    ],
)
def test_bad_input_is_named(args, kwargs, message):
    with pytest.raises(ValueError, match=message):
        grid_soundings(*args, **kwargs)


def test_a_patch_centred_behind_the_vehicle_keeps_its_offset():
    # Centre 30 m south and 4 m west of the vehicle: node (k, l) at north -30 + (k - 1) * 2, east -4 + (l - 2) * 2.
    out = grid_soundings([-8.0, -4.0, 0.1], [-32.0, -30.0, -28.2], [10.0, 11.0, 12.0], patch_shape=(3, 5), node_m=2.0, centre_m=(-4.0, -30.0))
    expected = np.full((3, 5), np.nan)
    expected[0, 0], expected[1, 2], expected[2, 4] = 10.0, 11.0, 12.0
    np.testing.assert_array_equal(out.patch.depth_m, expected)
    assert out.patch.centre_offset_m == (-4.0, -30.0) and (out.used, out.outside) == (3, 0)
    # The same soundings around the vehicle are all beyond a 3 x 5 patch.
    assert grid_soundings([-8.0, -4.0, 0.1], [-32.0, -30.0, -28.2], [1.0, 1.0, 1.0], patch_shape=(3, 5), node_m=2.0).used == 0


def test_a_patch_is_as_old_as_its_soundings_on_average():
    out = grid_soundings([0.0, 1.0, 2.0, 50.0], [0.0, 0.0, 0.0, 0.0], [1.0, 2.0, 3.0, 4.0], patch_shape=(3, 3), node_m=2.0,
                         age_s=np.array([10.0, 20.0, 60.0, 99.0]))
    assert out.used == 3 and out.patch.age_s == pytest.approx(30.0)  # the sounding beyond the patch is not counted
    assert grid_soundings([0.0], [0.0], [1.0], patch_shape=(3, 3), node_m=2.0).patch.age_s == 0.0


def test_soundings_centre_is_the_middle_of_their_extent():
    assert soundings_centre([-10.0, 30.0, 0.0], [-60.0, -20.0, -50.0]) == (10.0, -40.0)
    with pytest.raises(ValueError, match="at least one sounding"):
        soundings_centre([], [])
    with pytest.raises(ValueError, match="finite"):
        soundings_centre([0.0, np.inf], [0.0, 1.0])
