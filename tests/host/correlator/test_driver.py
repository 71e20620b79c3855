"""``CorrelatorDriver`` against the reference device in-process: exact results, pieces, tiles, retries."""

import itertools

import numpy as np
import pytest

from lost import model
from lost.host.correlator import correlation
from lost.host.correlator.backends import DeviceBackend
from lost.host.correlator.driver import CorrelatorDriver, DeviceError, DeviceTimeout
from lost.host.correlator.transports import InProcessTransport
from lost.model.device import DeviceModel, reference_info
from lost.model.protocol import Command, ErrorCode, encode_frame

INFO = reference_info(tile_shape=(32, 32), area_shape=(16, 16), patch_shape=(4, 4), exclusion_radius=2)


def _driver(**transport_options):
    device = DeviceModel(INFO)
    return CorrelatorDriver(InProcessTransport(device, **transport_options)), device


def _map(shape=(60, 70), seed=5):
    return np.random.default_rng(seed).integers(-32768, 32768, shape).astype(np.int16)


def test_identify_reports_the_devices_sizes():
    driver, _ = _driver()
    info = driver.identify()
    assert info == INFO and info.surface_shape == (13, 13) and info.variant_name == "window_correlator_l1"


@pytest.mark.parametrize("mean_compensation", [True, False])
def test_one_area_gives_the_devices_own_best_fit(mean_compensation):
    driver, _ = _driver()
    terrain = _map()
    patch = terrain[20:24, 30:34].copy()
    mask = np.ones((4, 4), bool)
    mask[1, 2] = False
    backend = DeviceBackend("rtl", lambda: driver._transport)
    backend._driver = driver
    result = correlation(terrain, patch, mask=mask, mean_compensation=mean_compensation, backend=backend,
                         area=(15, 25, 13, 13), exclusion_radius=2)
    expected = model.correlate(terrain[15:31, 25:41], patch, mask=mask, mean_compensation=mean_compensation)
    np.testing.assert_array_equal(result.surface, expected)
    fit = model.best_fit(expected, exclusion_radius=2)
    assert result.best_from == "hardware"
    assert result.best == model.Placement(fit.i + 15, fit.j + 25, fit.value)
    assert result.runner_up == model.Placement(fit.runner_up.i + 15, fit.runner_up.j + 25, fit.runner_up.value)


@pytest.mark.parametrize(("map_shape", "patch_shape"), [((60, 70), (4, 4)), ((9, 40), (3, 2)), ((5, 5), (4, 4)), ((33, 17), (1, 4))])
def test_any_map_and_smaller_patch_is_exact_in_pieces(map_shape, patch_shape):
    driver, _ = _driver()
    terrain = _map(map_shape)
    rng = np.random.default_rng(1)
    patch = rng.integers(-32768, 32768, patch_shape).astype(np.int16)
    mask = rng.random(patch_shape) < 0.8
    mask.flat[0] = True
    backend = DeviceBackend("rtl", lambda: None)
    backend._driver = driver
    for mean_compensation in (True, False):
        result = correlation(terrain, patch, mask=mask, mean_compensation=mean_compensation, backend=backend)
        np.testing.assert_array_equal(result.surface, model.correlate(terrain, patch, mask=mask, mean_compensation=mean_compensation))


def test_the_tile_stays_resident_while_the_area_stays_inside_it():
    driver, _ = _driver()
    terrain = _map((200, 200))
    patch = terrain[50:54, 60:64].copy()
    mask = np.ones((4, 4), bool)
    for i0, j0 in [(40, 50), (41, 52), (45, 60), (56, 66)]:  # inside the tile loaded for the first
        driver.correlate(terrain, patch, mask, True, area=(i0, j0, 13, 13), exclusion_radius=2)
    assert driver.stats["tile_loads"] == 1
    driver.correlate(terrain, patch, mask, True, area=(100, 100, 13, 13), exclusion_radius=2)
    assert driver.stats["tile_loads"] == 2
    # The same content in another array (a copy) is recognized as the resident tile's map.
    driver.correlate(terrain.copy(), patch, mask, True, area=(101, 101, 13, 13), exclusion_radius=2)
    assert driver.stats["tile_loads"] == 2


def test_a_changed_map_is_reloaded():
    driver, _ = _driver()
    terrain = _map((40, 40))
    patch = terrain[5:9, 6:10].copy()
    mask = np.ones((4, 4), bool)
    first = driver.correlate(terrain, patch, mask, True, area=(0, 0, 13, 13)).surface
    terrain[10, 10] += 7  # inside the resident tile
    second = driver.correlate(terrain, patch, mask, True, area=(0, 0, 13, 13)).surface
    np.testing.assert_array_equal(second, model.correlate(terrain[:16, :16], patch))
    assert not np.array_equal(first, second)


def _flip_once(at):
    calls = itertools.count()

    def damage(data):
        if next(calls) == at and data:
            data = bytearray(data)
            data[len(data) // 2] ^= 0x10
            return bytes(data)
        return data

    return damage


def _drop_once(at):
    calls = itertools.count()
    return lambda data: b"" if next(calls) == at else data


def _truncate_once(at):
    calls = itertools.count()
    return lambda data: data[:7] if next(calls) == at else data


@pytest.mark.parametrize("fault", ["request_flipped", "reply_flipped", "reply_lost", "request_truncated"])
def test_the_driver_retries_damaged_and_lost_frames(fault):
    options = {
        "request_flipped": {"damage_out": _flip_once(1)},
        "reply_flipped": {"damage_in": _flip_once(1)},
        "reply_lost": {"damage_in": _drop_once(1)},
        "request_truncated": {"damage_out": _truncate_once(1)},
    }[fault]
    driver, _ = _driver(**options)
    terrain = _map((16, 16))
    patch = terrain[3:7, 2:6].copy()
    out = driver.correlate(terrain, patch, np.ones((4, 4), bool), True, area=(0, 0, 13, 13))
    np.testing.assert_array_equal(out.surface, model.correlate(terrain, patch))
    assert driver.stats["retries"] == 1


def test_stale_replies_are_dropped_by_sequence_number():
    driver, device = _driver()
    driver.identify()
    # A reply the host never read (it stopped reading): it is still in the pipe when the next request goes out.
    driver._transport._pending += device.receive(encode_frame(200, Command.IDENTIFY))
    assert driver.identify() == INFO
    assert driver.stats["stale_replies"] == 1 and driver.stats["retries"] == 0


def test_a_refusal_names_the_error():
    driver, _ = _driver()
    with pytest.raises(DeviceError, match="refused START: error STATE") as raised:
        driver.start(0, 0)
    assert raised.value.code == ErrorCode.STATE
    with pytest.raises(DeviceError, match="refused START: error RANGE"):
        driver.start(17, 0)


def test_a_dead_device_times_out_after_the_retries():
    driver, _ = _driver(damage_in=lambda data: b"")
    with pytest.raises(DeviceTimeout, match="no valid reply to IDENTIFY after 4 attempts"):
        driver.identify()


def test_a_patch_larger_than_the_devices_is_refused():
    driver, _ = _driver()
    with pytest.raises(ValueError, match="patches up to 4 x 4, got 5 x 4"):
        driver.correlate(_map((20, 20)), np.zeros((5, 4), np.int16), np.ones((5, 4), bool), True, area=(0, 0, 4, 4))


def test_reset_forgets_the_patch():
    driver, _ = _driver()
    terrain = _map((16, 16))
    driver.correlate(terrain, terrain[:4, :4].copy(), np.ones((4, 4), bool), True, area=(0, 0, 13, 13))
    driver.reset()
    with pytest.raises(DeviceError, match="READ_RESULT: error STATE"):
        driver.read_result()


def test_a_tile_reload_sends_only_the_changed_words():
    driver, device = _driver()
    terrain = _map((40, 40))
    patch, mask = terrain[:4, :4].copy(), np.ones((4, 4), bool)
    driver.correlate(terrain, patch, mask, True, area=(0, 0, 13, 13))
    sent = driver.stats["bytes_out"]
    terrain[3, 5] += 1
    terrain[20, 1] -= 1
    out = driver.correlate(terrain, patch, mask, True, area=(0, 0, 13, 13))
    np.testing.assert_array_equal(device.tile, terrain[:32, :32])
    np.testing.assert_array_equal(out.surface, model.correlate(terrain[:16, :16], patch))
    # Two one-word LOAD_TILE frames (13 bytes each), ORIGIN, START and the surface reads; no tile.
    assert driver.stats["bytes_out"] - sent < 300
