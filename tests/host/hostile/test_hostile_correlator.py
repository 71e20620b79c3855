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


# ---- a device or a port that misbehaves -------------------------------------------------------------

import dataclasses  # noqa: E402
import time  # noqa: E402

from lost.host.correlator.driver import CorrelatorDriver, DeviceError, DeviceTimeout  # noqa: E402
from lost.host.correlator.transports import InProcessTransport, Transport  # noqa: E402
from lost.model.device import DeviceModel, reference_info  # noqa: E402

DEVICE = reference_info(tile_shape=(32, 32), area_shape=(16, 16), patch_shape=(4, 4), exclusion_radius=2)


class _Chatter(Transport):
    """A port on which something else talks: every read brings ``burst`` bytes that never form a frame."""

    def __init__(self, burst: bytes, every_s: float, timeout_s: float = 0.02):
        self._burst, self._every_s, self.timeout_s = burst, every_s, timeout_s

    def write(self, data: bytes) -> None:
        pass

    def read(self, size: int, timeout: float) -> bytes:
        time.sleep(min(self._every_s, timeout))
        return self._burst if self._every_s <= timeout else b""


@pytest.mark.parametrize("burst, every_s", [(b"\x55", 0.015), (b"\x5a" * 512, 0.0)], ids=["slow_drip", "noisy_line"])
def test_a_port_that_keeps_sending_bytes_that_form_no_frame_times_out(burst, every_s):
    driver = CorrelatorDriver(_Chatter(burst, every_s), retries=1)
    begin = time.monotonic()
    with pytest.raises(DeviceTimeout, match="no valid reply to IDENTIFY after 2 attempts"):
        driver.identify()
    # 2 attempts of at most 8 timeouts of 0.02 s each, however the bytes come.
    assert time.monotonic() - begin < 2 * 8 * 0.02 + 0.5
    assert driver.stats["noise_replies"] >= 1


BAD_DEVICES = {
    "tile_0_x_0": (dict(tile_shape=(0, 0)), "reports a 0 x 0 tile: it has no node"),
    "patch_0_x_4": (dict(patch_shape=(0, 4)), "reports a 0 x 4 patch"),
    "area_wider_than_tile": (dict(area_shape=(16, 40)), "each must fit within the next"),
    "patch_taller_than_area": (dict(patch_shape=(20, 4)), "each must fit within the next"),
    "narrow_adders": (dict(value_bits=20), "sums are 20 bits wide but a 4 x 4 patch of 16-bit words needs 24"),
    "8_bit_words": (dict(depth_bits=8), "takes 8-bit depth words"),
}


@pytest.mark.parametrize("change, message", BAD_DEVICES.values(), ids=BAD_DEVICES.keys())
def test_a_device_that_cannot_serve_the_requests_is_refused_at_identify(change, message):
    liar = dataclasses.replace(DEVICE, **change)
    device = DeviceModel(DEVICE)
    transport = InProcessTransport(device)
    driver = CorrelatorDriver(transport)
    device.info = liar
    with pytest.raises(DeviceError, match=message):
        driver.identify()


def test_a_whole_map_correlation_holds_little_more_than_its_surface():
    """``lost correlate`` on a large map: no copy of the surface, no index arrays of its size, no prefix sum without holes."""
    import tracemalloc

    from lost.host.correlator import correlation

    terrain = np.random.default_rng(3).integers(-3000, 3000, (1024, 1024)).astype(np.int16)
    patch = terrain[100:116, 200:216].copy()
    tracemalloc.start()
    try:
        result = correlation(terrain, patch, holes=np.zeros(terrain.shape, bool))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert (result.best.i, result.best.j, result.best.value) == (100, 200, 0)
    # The surface (int64) and its valid mask (bool) are the result; the model's best_fit alone took 4 surfaces more.
    assert peak < 2 * result.surface.nbytes
