import re

import numpy as np
import pytest

from lost.model import bits_for, correlate, correlator_widths, placement_widths, widths
from lost.model.correlator import DEPTH_MAX, DEPTH_MIN

# A difference d = M - S at its extremes: M and S at opposite ends of the word.
LOW = (DEPTH_MIN, DEPTH_MAX)  # d = -D
HIGH = (DEPTH_MAX, DEPTH_MIN)  # d = +D


def _extreme_case(h, w, high_nodes):
    """Map equal to the patch's size, so V has a single placement; `high_nodes` nodes get d = +D."""
    flags = np.zeros(h * w, dtype=bool)
    flags[:high_nodes] = True
    terrain = np.where(flags, HIGH[0], LOW[0]).reshape(h, w).astype(np.int16)
    patch = np.where(flags, HIGH[1], LOW[1]).reshape(h, w).astype(np.int16)
    return terrain, patch


@pytest.mark.parametrize("h, w", [(1, 1), (1, 2), (3, 3), (10, 10), (16, 16), (5, 7)])
def test_surface_bound_is_reached(h, w):
    n = h * w
    terrain, patch = _extreme_case(h, w, n // 2)
    bound = correlator_widths(h, w)
    V = correlate(terrain, patch)
    assert V[0, 0] == bound.surface.hi
    assert V[0, 0] < 2**bound.surface.bits
    plain = correlate(terrain, patch, mean_compensation=False)
    assert plain[0, 0] == bound.surface_plain.hi


@pytest.mark.parametrize("h, w", [(2, 2), (10, 10), (16, 16)])
def test_term_bound_is_reached(h, w):
    """One node at d = +D and the rest at -D makes that node's term (n - 1) * 2 * D."""
    terrain, patch = _extreme_case(h, w, 1)
    n = h * w
    m, s = terrain.astype(np.int64).ravel(), patch.astype(np.int64).ravel()
    terms = n * (m - s) - (m.sum() - s.sum())
    bound = correlator_widths(h, w)
    assert terms.max() == bound.term.hi == bound.abs_term.hi
    assert (n * m - m.sum()).max() == bound.centred_depth.hi


def test_surface_bound_holds_over_random_extremes():
    rng = np.random.default_rng(0)
    bound = correlator_widths(4, 4).surface.hi
    for _ in range(200):
        terrain = rng.choice([DEPTH_MIN, DEPTH_MAX], (4, 4)).astype(np.int16)
        patch = rng.choice([DEPTH_MIN, DEPTH_MAX], (4, 4)).astype(np.int16)
        assert correlate(terrain, patch)[0, 0] <= bound


def test_docstring_table_is_what_the_function_computes():
    rows = re.findall(r"^(\d+) x (\d+)((?:\s+\d+){8})\s*$", widths.__doc__, flags=re.M)
    assert len(rows) == 2
    columns = ["window_sum", "scaled_depth", "centred_depth", "term", "abs_term", "surface", "surface_plain", "accumulator"]
    for h, w, numbers in rows:
        computed = correlator_widths(int(h), int(w)).as_dict()
        assert [int(x) for x in numbers.split()] == [computed[c][0] for c in columns]


@pytest.mark.parametrize(
    "lo, hi, expected",
    [(0, 0, (1, False)), (0, 1, (1, False)), (0, 255, (8, False)), (0, 256, (9, False)),
     (-1, 0, (1, True)), (-128, 127, (8, True)), (-129, 127, (9, True)), (-128, 128, (9, True))],
)
def test_bits_for(lo, hi, expected):
    assert bits_for(lo, hi) == expected


def test_placement_widths():
    assert placement_widths((501, 501), (10, 10)) == (9, 9)
    assert placement_widths((1024, 1024), (16, 16)) == (10, 10)
    assert placement_widths((10, 10), (10, 10)) == (1, 1)
    with pytest.raises(ValueError, match="larger"):
        placement_widths((4, 4), (5, 1))


@pytest.mark.parametrize("args", [(0, 3), (3, -1), (3, 3, 1), (2.5, 3)])
def test_bad_sizes_are_named(args):
    with pytest.raises(ValueError):
        correlator_widths(*args)
