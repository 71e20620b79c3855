"""The host's ``rtl`` backend: ``lost.host.correlate`` answered by the generated Verilog on Verilator."""

from pathlib import Path

import numpy as np
import pytest

from lost.host import correlate

BUILD = Path(__file__).resolve().parents[2] / "build" / "sim" / "rtl"


@pytest.fixture
def rtl_cache(monkeypatch):
    monkeypatch.setenv("LOST_RTL_CACHE", str(BUILD))
    monkeypatch.delenv("LOST_RTL_VARIANT", raising=False)
    return BUILD


def test_the_rtl_backend_returns_the_models_surface(rtl_cache):
    rng = np.random.default_rng(7)
    terrain = rng.integers(-32768, 32768, (24, 31)).astype(np.int16)
    patch = terrain[9:15, 3:8].copy()
    patch[0, 0], patch[5, 4] = -32768, 32767  # extreme words through the widest intermediates
    mask = rng.random(patch.shape) < 0.75
    for mean_compensation in (True, False):
        rtl = correlate(terrain, patch, mask=mask, mean_compensation=mean_compensation, backend="rtl")
        model = correlate(terrain, patch, mask=mask, mean_compensation=mean_compensation, backend="model")
        np.testing.assert_array_equal(rtl, model)
    # One build for the shape, reused by the second call.
    assert [p.name for p in rtl_cache.iterdir() if p.is_dir() and p.name.startswith("window")] == ["window_correlator_l1-24x31-6x5"]


def test_an_unknown_rtl_variant_is_named(rtl_cache, monkeypatch):
    monkeypatch.setenv("LOST_RTL_VARIANT", "window_correlator_l3")
    with pytest.raises(ValueError, match="LOST_RTL_VARIANT must be one of"):
        correlate(np.zeros((8, 8), np.int16), np.ones((2, 2), np.int16), backend="rtl")
