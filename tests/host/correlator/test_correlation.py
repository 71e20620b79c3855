"""``correlation``: one result type for every backend; the valid placements decided in one place."""

import numpy as np
import pytest

from lost import model
from lost.host.correlator import BACKENDS, correlation, valid_placements


def _case(seed=3, shape=(40, 50), patch_shape=(6, 5)):
    rng = np.random.default_rng(seed)
    terrain = rng.integers(-2000, 2000, shape).astype(np.int16)
    patch = terrain[11 : 11 + patch_shape[0], 17 : 17 + patch_shape[1]].copy()
    return terrain, patch


@pytest.mark.parametrize("backend", ["software", "model"])
def test_best_fit_and_runner_up_match_the_model(backend):
    terrain, patch = _case()
    result = correlation(terrain, patch, backend=backend, exclusion_radius=2)
    expected = model.correlate(terrain, patch)
    fit = model.best_fit(expected, exclusion_radius=2)
    np.testing.assert_array_equal(result.surface, expected)
    assert result.valid.all() and result.origin == (0, 0) and result.backend == backend
    assert result.best == fit.best == model.Placement(11, 17, 0)
    assert result.runner_up == fit.runner_up and result.best_from == "host"


def test_an_area_past_the_edges_marks_those_placements_invalid():
    terrain, patch = _case()
    full = model.correlate(terrain, patch)
    result = correlation(terrain, patch, area=(-3, 40, 10, 12))
    assert result.surface.shape == result.valid.shape == (10, 12)
    # Rows -3..-1 and columns past 50 - 5 = 45 leave the map.
    assert not result.valid[:3].any() and not result.valid[:, 6:].any() and result.valid[3:, :6].all()
    np.testing.assert_array_equal(result.surface[3:, :6], full[0:7, 40:46])
    assert (result.surface[~result.valid] == 0).all()
    valid_values = np.where(result.valid, result.surface, np.iinfo(np.int64).max)
    r, c = np.unravel_index(np.argmin(valid_values), valid_values.shape)
    assert result.best == model.Placement(int(r) - 3, int(c) + 40, int(valid_values[r, c]))


def test_holes_exclude_every_placement_whose_window_touches_one():
    terrain, patch = _case()
    holes = np.zeros(terrain.shape, bool)
    holes[13, 19] = True  # inside the true placement's window
    result = correlation(terrain, patch, holes=holes, exclusion_radius=1)
    valid = result.valid
    assert not valid[11, 17] and not valid[13 - 5, 19 - 4] and valid[13 - 6, 19] and valid[14, 19]
    assert valid.sum() == valid.size - 6 * 5
    assert result.best is not None and not (8 <= result.best.i <= 13 and 15 <= result.best.j <= 19)


def test_no_valid_placement_gives_no_best_fit():
    terrain, patch = _case()
    holes = np.zeros(terrain.shape, bool)
    holes[::4, ::4] = True
    result = correlation(terrain, patch, holes=holes)
    assert not result.valid.any() and result.best is None and result.runner_up is None and not result.any_valid
    assert np.isnan(result.distinctness)


def test_runner_up_is_none_when_no_valid_placement_lies_outside_the_radius():
    terrain, _ = _case(shape=(12, 12))
    patch = terrain[2:8, 3:9].copy()
    holes = np.zeros(terrain.shape, bool)
    holes[0, :] = holes[:, 0] = True
    result = correlation(terrain, patch, holes=holes, exclusion_radius=5, area=(0, 0, 7, 7))
    assert result.best is not None and result.runner_up is None and result.distinctness == float("inf")


def test_valid_placements_refuses_a_hole_mask_of_the_wrong_shape():
    with pytest.raises(ValueError, match="holes must be a boolean array of the map's shape"):
        valid_placements((10, 10), (3, 3), (0, 0, 8, 8), np.zeros((9, 10), bool))


def test_an_area_without_placements_is_refused():
    terrain, patch = _case()
    with pytest.raises(ValueError, match="at least one placement"):
        correlation(terrain, patch, area=(0, 0, 0, 4))


def test_every_backend_is_listed():
    assert set(BACKENDS) == {"software", "model", "rtl", "fpga"}


def test_valid_placements_matches_a_window_by_window_check_over_areas_reaching_off_the_map():
    rng = np.random.default_rng(7)
    for _ in range(200):
        H, W = (int(v) for v in rng.integers(5, 30, 2))
        h, w = (int(v) for v in rng.integers(1, min(H, W) + 1, 2))
        holes = rng.random((H, W)) < rng.choice([0.01, 0.1, 0.3])
        i0, j0 = int(rng.integers(-10, H + 5)), int(rng.integers(-10, W + 5))
        rows, cols = (int(v) for v in rng.integers(1, 25, 2))
        want = np.array([[0 <= i <= H - h and 0 <= j <= W - w and not holes[i : i + h, j : j + w].any()
                          for j in range(j0, j0 + cols)] for i in range(i0, i0 + rows)])
        assert np.array_equal(valid_placements((H, W), (h, w), (i0, j0, rows, cols), holes), want)


@pytest.mark.parametrize("seed", range(6))
def test_choose_fit_block_by_block_is_the_models_best_fit_on_the_masked_surface(seed, monkeypatch):
    """Ties, invalid placements and block edges: the same best fit and runner-up as the golden model's."""
    from lost.host.correlator import result as result_module
    from lost.host.correlator.result import choose_fit

    monkeypatch.setattr(result_module, "_FIT_BLOCK_ROWS", 3)  # many block edges on a small surface
    rng = np.random.default_rng(seed)
    shape = tuple(int(v) for v in rng.integers(1, 14, 2))
    surface = rng.integers(0, 6, shape).astype(np.int64)  # few values: many ties
    valid = rng.random(shape) > 0.3
    radius = int(rng.integers(0, 4))
    got = choose_fit(surface, valid, radius)
    if not valid.any():
        assert got is None
        return
    ceiling = np.iinfo(np.int64).max
    want = model.best_fit(np.where(valid, surface, ceiling), exclusion_radius=radius)
    assert (got.i, got.j, got.value) == (want.i, want.j, want.value)
    ru = want.runner_up if want.runner_up is not None and valid[want.runner_up.i, want.runner_up.j] else None
    assert got.runner_up == ru


@pytest.mark.parametrize("counting", ["as shipped", "hole by hole", "node by node", "fft"])
def test_valid_placements_count_only_the_holes_under_the_patchs_valid_nodes(monkeypatch, counting):
    """Against a node-by-node check, over areas reaching off the map and FFT blocks of a few rows, each way of counting
    the holes forced in turn."""
    from lost.host.correlator import result as result_module

    monkeypatch.setattr(result_module, "_HOLE_BLOCK_ROWS", 3)
    forced = {"hole by hole": (10**9, 0), "node by node": (-1, 10**9), "fft": (-1, -1)}.get(counting)
    if forced is not None:
        monkeypatch.setattr(result_module, "_FEW_HOLES", forced[0])
        monkeypatch.setattr(result_module, "_FEW_NODES", forced[1])
    rng = np.random.default_rng(11)
    for _ in range(200):
        H, W = (int(v) for v in rng.integers(5, 30, 2))
        h, w = (int(v) for v in rng.integers(1, min(H, W) + 1, 2))
        holes = rng.random((H, W)) < rng.choice([0.05, 0.3, 0.8])
        mask = rng.random((h, w)) < rng.choice([0.0, 0.3, 0.9, 1.0])
        i0, j0 = int(rng.integers(-10, H + 5)), int(rng.integers(-10, W + 5))
        rows, cols = (int(v) for v in rng.integers(1, 25, 2))
        want = np.array([[0 <= i <= H - h and 0 <= j <= W - w and not (holes[i : i + h, j : j + w] & mask).any()
                          for j in range(j0, j0 + cols)] for i in range(i0, i0 + rows)])
        assert np.array_equal(valid_placements((H, W), (h, w), (i0, j0, rows, cols), holes, mask), want)


def test_valid_placements_refuses_a_mask_of_another_shape():
    with pytest.raises(ValueError, match="mask must be a boolean array of the patch's shape"):
        valid_placements((10, 10), (3, 3), (0, 0, 8, 8), np.zeros((10, 10), bool), np.ones((3, 2), bool))


@pytest.mark.parametrize("backend", ["software", "model"])
def test_a_hole_band_under_the_patchs_empty_part_leaves_the_true_placement_valid_and_bit_exact(backend):
    """A swath with no soundings on its west third over a map whose holes run under that third: the fill never counts."""
    terrain, _ = _case(shape=(40, 50))
    patch = terrain[11:19, 17:26].copy()
    mask = np.ones(patch.shape, bool)
    mask[:, :3] = False  # no sounding on the patch's three west columns
    holes = np.zeros(terrain.shape, bool)
    holes[:, 17:20] = True  # a band of holes under them at the true placement
    filled = [terrain.copy(), terrain.copy()]
    filled[0][holes], filled[1][holes] = 1999, -1999  # two different fills of the holes
    results = [correlation(t, patch, mask=mask, holes=holes, backend=backend) for t in filled]
    for result, t in zip(results, filled, strict=True):
        assert result.valid[11, 17] and result.best == model.Placement(11, 17, 0)
        np.testing.assert_array_equal(np.where(result.valid, result.surface, 0),
                                      np.where(result.valid, model.correlate(t, patch, mask=mask), 0))
    # Where the band lies under a valid node the placement is refused; elsewhere the two fills give the same V.
    assert not results[0].valid[11, 15] and np.array_equal(results[0].valid, results[1].valid)
    np.testing.assert_array_equal(results[0].surface[results[0].valid], results[1].surface[results[1].valid])
    # The whole window's rule (no mask) would have refused the true placement.
    assert not correlation(terrain, patch, holes=holes, backend=backend).valid[11, 17]


def test_valid_placements_allow_a_share_of_the_valid_nodes_on_holes(monkeypatch):
    from lost.host.correlator import result as result_module

    monkeypatch.setattr(result_module, "_HOLE_BLOCK_ROWS", 4)
    rng = np.random.default_rng(12)
    for _ in range(150):
        H, W = (int(v) for v in rng.integers(5, 25, 2))
        h, w = (int(v) for v in rng.integers(1, min(H, W) + 1, 2))
        holes = rng.random((H, W)) < rng.choice([0.05, 0.3])
        mask = None if rng.random() < 0.3 else rng.random((h, w)) < 0.8
        share = float(rng.choice([0.0, 0.1, 0.25, 0.5]))
        counted = np.ones((h, w), bool) if mask is None else mask
        allowed = int(share * counted.sum())
        i0, j0 = int(rng.integers(-5, H)), int(rng.integers(-5, W))
        rows, cols = (int(v) for v in rng.integers(1, 20, 2))
        want = np.array([[0 <= i <= H - h and 0 <= j <= W - w and (holes[i : i + h, j : j + w] & counted).sum() <= allowed
                          for j in range(j0, j0 + cols)] for i in range(i0, i0 + rows)])
        assert np.array_equal(valid_placements((H, W), (h, w), (i0, j0, rows, cols), holes, mask, share), want)
    for bad in (-0.1, 1.0, float("nan")):
        with pytest.raises(ValueError, match="max_hole_share"):
            valid_placements((10, 10), (3, 3), (0, 0, 8, 8), None, None, bad)
