"""The map made ready for the correlator: word scale, and the hole policy."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from lost import model
from lost.host.grid import Grid
from lost.host.nav import PreparedMap


def _grid(depth):
    return Grid(np.asarray(depth, float), 0.0, 0.0, 10.0)


def test_scale_and_offset_hold_the_map():
    depth = np.linspace(900.0, 1100.0, 60).reshape(6, 10)
    prepared = PreparedMap(grid=_grid(depth))
    assert prepared.offset_m == 1000.0
    # The finest step that holds +-100 m in half the word range: 0.01 m words hold +-327 m, half is +-163 m.
    assert prepared.lsb_m == 0.01
    assert np.allclose(model.dequantize(prepared.words, prepared.lsb_m, offset_m=prepared.offset_m), depth, atol=0.005)


def test_a_given_step_is_used():
    assert PreparedMap(grid=_grid(np.full((4, 4), 50.0)), lsb_m=0.5).lsb_m == 0.5


def test_holes_are_filled_and_every_touching_placement_is_flagged():
    depth = np.arange(48, dtype=float).reshape(6, 8)
    depth[3, 4] = np.nan
    prepared = PreparedMap(grid=_grid(depth))
    assert prepared.holes.sum() == 1
    words = prepared.words
    assert words.dtype == np.int16
    # Filled with the nearest valid node's depth, which is one of its four neighbours.
    neighbours = [depth[2, 4], depth[4, 4], depth[3, 3], depth[3, 5]]
    filled = model.dequantize(words[3, 4], prepared.lsb_m, offset_m=prepared.offset_m)
    assert min(abs(filled - n) for n in neighbours) < prepared.lsb_m
    touching = PreparedMap(grid=_grid(depth), max_hole_share=0.0).placements_touching_holes((2, 3))
    assert touching.shape == (5, 6)
    expected = np.zeros((5, 6), dtype=bool)
    expected[2:4, 2:5] = True  # windows with top-left rows 2..3 and cols 2..4 cover node (3, 4)
    assert np.array_equal(touching, expected)


def test_patch_quantization_masks_and_counts():
    prepared = PreparedMap(grid=_grid(np.linspace(990.0, 1010.0, 16).reshape(4, 4)))
    patch = np.array([[1000.0, np.nan], [1e6, 1001.0]])
    words, mask, dropped = prepared.quantize_patch(patch)
    assert np.array_equal(mask, [[True, False], [False, True]])
    assert dropped == 1
    assert words[0, 0] == 0 and words[1, 1] == round(1.0 / prepared.lsb_m)


def test_no_valid_node_is_an_error():
    with pytest.raises(ValueError, match="no valid depth"):
        PreparedMap(grid=_grid(np.full((3, 3), np.nan)))


def test_a_patch_larger_than_the_map_is_an_error():
    with pytest.raises(ValueError, match="does not fit"):
        PreparedMap(grid=_grid(np.zeros((3, 3)))).placements_touching_holes((4, 2))


@given(
    holes=hnp.arrays(bool, st.tuples(st.integers(1, 12), st.integers(1, 12)), elements=st.booleans()),
    h=st.integers(1, 5),
    w=st.integers(1, 5),
)
def test_touching_holes_matches_a_naive_scan(holes, h, w):
    rows, cols = holes.shape
    if holes.all() or h > rows or w > cols:
        return
    depth = np.where(holes, np.nan, 100.0 + np.arange(holes.size).reshape(holes.shape))
    touching = PreparedMap(grid=_grid(depth), max_hole_share=0.0).placements_touching_holes((h, w))
    naive = np.array([[holes[i : i + h, j : j + w].any() for j in range(cols - w + 1)] for i in range(rows - h + 1)])
    assert np.array_equal(touching, naive.reshape(rows - h + 1, cols - w + 1))


@given(
    holes=hnp.arrays(bool, st.tuples(st.integers(1, 20), st.integers(1, 20)), elements=st.booleans()),
    mask=hnp.arrays(bool, st.tuples(st.integers(1, 6), st.integers(1, 6)), elements=st.booleans()),
    share=st.sampled_from([0.0, 0.1, 0.3]),
)
def test_holes_under_the_patchs_valid_nodes_match_a_naive_count_few_or_many(holes, mask, share):
    from lost.host.correlator import valid_placements
    (rows, cols), (h, w) = holes.shape, mask.shape
    if h > rows or w > cols:
        return
    valid = valid_placements(holes.shape, mask.shape, (0, 0, rows - h + 1, cols - w + 1), holes, mask, share)
    allowed = int(share * mask.sum())
    naive = np.array([[(holes[i : i + h, j : j + w] & mask).sum() <= allowed for j in range(cols - w + 1)]
                      for i in range(rows - h + 1)])
    assert np.array_equal(valid, naive)


def test_a_share_of_the_patchs_soundings_may_lie_on_holes():
    depth = np.arange(100, dtype=float).reshape(10, 10)
    depth[4, 4] = depth[4, 5] = np.nan
    mask = np.ones((5, 5), bool)
    mask[0, 0] = False
    strict = PreparedMap(grid=_grid(depth), max_hole_share=0.0).placements_touching_holes((5, 5), mask=mask)
    tolerant = PreparedMap(grid=_grid(depth), max_hole_share=0.05).placements_touching_holes((5, 5), mask=mask)
    # 24 valid nodes: 0.05 allows one on a hole. Placement (0, 1) covers both holes; (0, 0) covers only (4, 4);
    # (4, 4) covers both, but (4, 4) falls on the patch's empty corner: one counts.
    assert strict[0, 1] and tolerant[0, 1]
    assert strict[0, 0] and not tolerant[0, 0]
    assert strict[4, 4] and not tolerant[4, 4]
    with pytest.raises(ValueError, match="max_hole_share"):
        PreparedMap(grid=_grid(depth), max_hole_share=1.0)
