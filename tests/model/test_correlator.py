import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from strategies import correlation_cases, naive_correlate

from lost.host.terrain import synthetic_terrain
from lost.model import Placement, best_fit, correlate, quantize


@given(correlation_cases())
def test_correlate_matches_naive_definition(case):
    terrain, patch, mask, mean_compensation = case
    V = correlate(terrain, patch, mask=mask, mean_compensation=mean_compensation)
    assert V.dtype == np.int64
    assert V.shape == (terrain.shape[0] - patch.shape[0] + 1, terrain.shape[1] - patch.shape[1] + 1)
    np.testing.assert_array_equal(V, naive_correlate(terrain, patch, mask, mean_compensation).astype(np.int64))


def test_mean_compensation_ignores_a_constant_offset():
    rng = np.random.default_rng(3)
    terrain = rng.integers(-1000, 1000, (20, 20)).astype(np.int16)
    patch = terrain[4:9, 7:12] + np.int16(321)
    V = correlate(terrain, patch)
    assert V[4, 7] == 0
    assert correlate(terrain, patch, mean_compensation=False)[4, 7] == 321 * 25


def test_flat_terrain_gives_a_flat_surface():
    terrain = np.full((12, 9), -5, dtype=np.int16)
    patch = np.arange(12, dtype=np.int16).reshape(3, 4)
    V = correlate(terrain, patch)
    assert (V == V[0, 0]).all()


def test_integer_dtypes_other_than_int16_are_accepted_when_they_fit():
    terrain = np.arange(30, dtype=np.int64).reshape(5, 6)
    patch = np.array([[1, 2]], dtype=np.uint8)
    np.testing.assert_array_equal(correlate(terrain, patch), correlate(terrain.astype(np.int16), patch.astype(np.int16)))


@pytest.mark.parametrize(
    "terrain, patch, mask, message",
    [
        (np.zeros((5, 5)), np.zeros((2, 2), np.int16), None, "integer array"),
        (np.zeros((5, 5), np.int16), np.zeros((2, 2), np.float32), None, "integer array"),
        (np.zeros((5,), np.int16), np.zeros((2, 2), np.int16), None, "2-D"),
        (np.zeros((5, 5), np.int16), np.zeros((2, 2, 1), np.int16), None, "2-D"),
        (np.zeros((3, 5), np.int16), np.zeros((4, 2), np.int16), None, "larger than the terrain"),
        (np.zeros((5, 5), np.int16), np.zeros((2, 2), np.int16), np.ones((2, 3), bool), "shape"),
        (np.zeros((5, 5), np.int16), np.zeros((2, 2), np.int16), np.zeros((2, 2), bool), "no valid node"),
        (np.zeros((5, 5), np.int16), np.zeros((2, 2), np.int16), np.ones((2, 2), np.int8), "boolean"),
        (np.full((5, 5), 40000, np.int32), np.zeros((2, 2), np.int16), None, "outside the 16-bit"),
        ([[1, 2], [3, 4]], np.zeros((1, 1), np.int16), None, "numpy array"),
        (np.zeros((0, 5), np.int16), np.zeros((0, 1), np.int16), None, "empty"),
    ],
)
def test_bad_input_is_named(terrain, patch, mask, message):
    with pytest.raises(ValueError, match=message):
        correlate(terrain, patch, mask=mask)


def test_best_fit_breaks_ties_in_raster_order():
    V = np.array([[5, 1, 7], [1, 9, 1]], dtype=np.int64)
    fit = best_fit(V, exclusion_radius=0)
    assert (fit.i, fit.j, fit.value) == (0, 1, 1)
    assert fit.runner_up == Placement(1, 0, 1)


def test_runner_up_lies_outside_the_exclusion_radius():
    V = np.full((7, 7), 100, dtype=np.int64)
    V[3, 3] = 0
    V[4, 4] = 1  # inside radius 1: not a runner-up
    V[1, 5] = 50  # Chebyshev distance 2
    V[0, 0] = 60
    fit = best_fit(V, exclusion_radius=1)
    assert (fit.i, fit.j) == (3, 3)
    assert fit.runner_up == Placement(1, 5, 50)
    assert best_fit(V, exclusion_radius=2).runner_up == Placement(0, 0, 60)
    assert best_fit(V, exclusion_radius=0).runner_up == Placement(4, 4, 1)
    assert best_fit(V, exclusion_radius=6).runner_up is None


@given(hnp.arrays(np.int64, hnp.array_shapes(min_dims=2, max_dims=2, max_side=8), elements=st.integers(0, 20)), st.integers(0, 4))
def test_best_fit_matches_a_scan(V, radius):
    fit = best_fit(V, exclusion_radius=radius)
    cells = [(int(V[i, j]), i, j) for i in range(V.shape[0]) for j in range(V.shape[1])]
    value, i, j = min(cells)  # tuples order by value, then raster position
    assert (fit.value, fit.i, fit.j) == (value, i, j)
    outside = [c for c in cells if max(abs(c[1] - i), abs(c[2] - j)) > radius]
    if outside:
        ru = min(outside)
        assert fit.runner_up == Placement(ru[1], ru[2], ru[0])
    else:
        assert fit.runner_up is None


@pytest.mark.parametrize("bad", [-1, 1.5, True, "2"])
def test_best_fit_rejects_a_bad_radius(bad):
    with pytest.raises(ValueError, match="exclusion_radius"):
        best_fit(np.zeros((3, 3), np.int64), exclusion_radius=bad)


def test_best_fit_rejects_a_float_surface():
    with pytest.raises(ValueError, match="integer"):
        best_fit(np.zeros((3, 3)))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_noiseless_patch_is_found_where_it_was_cut(seed):
    floor_m = synthetic_terrain((120, 140), seed=seed)
    terrain = quantize(floor_m, 0.1, offset_m=1000.0)
    rng = np.random.default_rng(seed)
    i, j = int(rng.integers(0, 111)), int(rng.integers(0, 131))
    patch = terrain[i : i + 10, j : j + 10].copy()
    for mean_compensation in (True, False):
        fit = best_fit(correlate(terrain, patch, mean_compensation=mean_compensation), exclusion_radius=5)
        assert (fit.i, fit.j, fit.value) == (i, j, 0)
        assert fit.runner_up is not None and fit.runner_up.value > 0
