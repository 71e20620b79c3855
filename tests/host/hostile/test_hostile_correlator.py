"""Hostile calls of the correlator API: wrong types, shapes, modes and words are refused with the same message by every backend."""

from __future__ import annotations

import numpy as np
import pytest

from lost import model
from lost.host import correlate

RNG = np.random.default_rng(7)
TERRAIN = RNG.integers(-1000, 1000, (24, 30)).astype(np.int16)
PATCH = TERRAIN[5:10, 7:13].copy()

BAD_CALLS = {
    "mean_compensation_as_string_false": (dict(mean_compensation="False"), r"mean_compensation must be True or False, got 'False' \(str\)"),
    "mean_compensation_as_string_true": (dict(mean_compensation="true"), r"got 'true' \(str\)"),
    "mean_compensation_none": (dict(mean_compensation=None), r"got None \(NoneType\); it is not taken by truthiness"),
    "mean_compensation_int": (dict(mean_compensation=1), r"got 1 \(int\)"),
    "terrain_as_list": (dict(terrain=TERRAIN.tolist()), "terrain must be a numpy array, got list"),
    "terrain_of_floats": (dict(terrain=TERRAIN.astype(float)), "terrain must be an integer array"),
    "patch_3d": (dict(patch=PATCH[None]), "patch must be 2-D, got 3-D"),
    "patch_empty": (dict(patch=np.zeros((0, 5), np.int16)), "patch is empty"),
    "patch_larger_than_map": (dict(patch=np.zeros((25, 5), np.int16)), "larger than the terrain map"),
    "words_beyond_16_bits": (dict(terrain=TERRAIN.astype(np.int32) * 40), "outside the 16-bit depth word"),
    "mask_of_ints": (dict(mask=np.ones(PATCH.shape, int)), "mask must be a boolean array"),
    "mask_of_another_shape": (dict(mask=np.ones((5, 5), bool)), r"mask has shape \(5, 5\), but the patch has shape \(5, 6\)"),
    "mask_all_false": (dict(mask=np.zeros(PATCH.shape, bool)), "mask has no valid node"),
    "mask_as_list": (dict(mask=np.ones(PATCH.shape, bool).tolist()), "mask must be a numpy array, got list"),
    "unknown_backend": (dict(backend="fpga9000"), "unknown correlator backend 'fpga9000'"),
    "backend_none": (dict(backend=None), "unknown correlator backend None"),
}


@pytest.mark.parametrize("change, message", BAD_CALLS.values(), ids=BAD_CALLS.keys())
@pytest.mark.parametrize("backend", ["software", "model"])
def test_a_bad_call_is_refused_by_every_backend_alike(change, message, backend):
    call = dict(terrain=TERRAIN, patch=PATCH, mask=None, mean_compensation=True, backend=backend) | change
    with pytest.raises(ValueError, match=message):
        correlate(call.pop("terrain"), call.pop("patch"), **call)


@pytest.mark.parametrize("mode", [True, False, np.bool_(True), np.bool_(False)])
def test_a_real_boolean_picks_the_mode_and_both_backends_agree(mode):
    fast = correlate(TERRAIN, PATCH, mean_compensation=mode)
    np.testing.assert_array_equal(fast, correlate(TERRAIN, PATCH, mean_compensation=mode, backend="model"))
    assert model.best_fit(fast).i == 5 and model.best_fit(fast).j == 7


def test_the_golden_model_refuses_a_string_mode_too():
    with pytest.raises(ValueError, match="mean_compensation must be True or False"):
        model.correlate(TERRAIN, PATCH, mean_compensation="False")
