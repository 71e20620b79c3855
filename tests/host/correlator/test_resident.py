"""The resident correlator: every request is exactly ``correlation`` over its own area, from one backend call per patch."""

import numpy as np
import pytest

from lost.host.correlator import correlation
from lost.host.correlator.backends import DeviceBackend
from lost.host.correlator.resident import ResidentCorrelator
from lost.host.correlator.transports import InProcessTransport
from lost.model.device import DeviceModel, reference_info


def _map(shape=(70, 90), seed=4):
    return np.random.default_rng(seed).integers(-3000, 3000, shape).astype(np.int16)


def _same(a, b):
    assert a.origin == b.origin and a.exclusion_radius == b.exclusion_radius
    assert np.array_equal(a.surface, b.surface) and np.array_equal(a.valid, b.valid)
    assert a.best == b.best and a.runner_up == b.runner_up


@pytest.mark.parametrize("hole_share", [0.0, 0.01, 0.6])
def test_every_request_equals_a_correlation_of_its_own_area(hole_share):
    terrain = _map()
    rng = np.random.default_rng(1)
    holes = rng.random(terrain.shape) < hole_share if hole_share else None
    resident = ResidentCorrelator(terrain, holes=holes)
    for _record in range(6):
        r0, c0 = (int(v) for v in rng.integers(0, 55, 2))
        patch = terrain[r0 : r0 + 7, c0 : c0 + 6] + rng.integers(-20, 20, (7, 6)).astype(np.int16)
        mask = rng.random(patch.shape) > 0.2
        # Areas as the callers of one record ask: a search, a filter's span, a wider look-alike area past the edges.
        for area in [(r0 - 8, c0 - 8, 17, 17), (r0 - 2, c0 - 3, 5, 7), (r0 - 30, c0 - 30, 61, 61), (r0, c0, 1, 1)]:
            got = resident.correlation(patch, mask, area)
            want = correlation(terrain, patch, mask=mask, area=area, holes=holes)
            _same(got, want)
    assert resident.stats["patches"] == 6 and resident.stats["requests"] == 24


def test_a_moving_vehicles_records_are_each_correlated_once():
    terrain = _map((200, 200))
    resident = ResidentCorrelator(terrain)
    for record in range(20):
        r0, c0 = 60 + 2 * record, 70 + record  # the areas follow the vehicle
        patch = terrain[r0 : r0 + 8, c0 : c0 + 8].copy()
        for area in [(r0 - 5, c0 - 5, 11, 11), (r0 - 2, c0 - 2, 5, 5), (r0 - 40, c0 - 40, 81, 81)]:
            resident.correlation(patch, np.ones((8, 8), bool), area)
    # Only the first record widens its surface for the look-alike area; every later one starts wide enough.
    assert resident.stats["correlations"] == 20 + 1


def test_a_changed_patch_is_correlated_afresh_and_the_same_one_is_not():
    terrain = _map()
    resident = ResidentCorrelator(terrain)
    patch, mask = terrain[10:16, 20:26].copy(), np.ones((6, 6), bool)
    resident.correlation(patch, mask, (5, 15, 11, 11))
    resident.correlation(patch.copy(), mask, (5, 15, 11, 11))
    assert resident.stats["correlations"] == 1
    patch[0, 0] += 1
    got = resident.correlation(patch, mask, (5, 15, 11, 11))
    assert resident.stats["correlations"] == 2
    _same(got, correlation(terrain, patch, mask=mask, area=(5, 15, 11, 11)))


def test_a_device_keeps_its_tile_without_the_map_being_hashed(monkeypatch):
    import hashlib

    info = reference_info(tile_shape=(64, 64), area_shape=(24, 24), patch_shape=(6, 6), exclusion_radius=3)
    backend = DeviceBackend("inprocess", lambda: InProcessTransport(DeviceModel(info)))
    terrain = _map((60, 60))
    resident = ResidentCorrelator(terrain, backend=backend)
    calls = []
    real = hashlib.blake2b
    monkeypatch.setattr(hashlib, "blake2b", lambda *a, **k: calls.append(1) or real(*a, **k))
    for r0 in (10, 12, 14):
        patch = terrain[r0 : r0 + 6, 20:26].copy()
        got = resident.correlation(patch, np.ones((6, 6), bool), (r0 - 5, 15, 11, 11))
        _same(got, correlation(terrain, patch, area=(r0 - 5, 15, 11, 11)))
    assert calls == []
    assert backend.driver.stats["tile_loads"] == 1


def test_bad_inputs_are_refused_with_the_correlators_messages():
    resident = ResidentCorrelator(_map())
    with pytest.raises(ValueError, match="larger than the terrain map"):
        resident.correlation(np.zeros((80, 5), np.int16), np.ones((80, 5), bool), (0, 0, 1, 1))
    with pytest.raises(ValueError, match="at least one placement"):
        resident.correlation(np.zeros((5, 5), np.int16), np.ones((5, 5), bool), (0, 0, 0, 3))
    with pytest.raises(ValueError, match="holes must be a boolean array"):
        ResidentCorrelator(_map(), holes=np.ones((3, 3), bool))
