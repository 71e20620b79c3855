import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from strategies import DEPTH, correlation_cases

from lost import model
from lost.host import BACKENDS, correlate
from lost.host.correlator import software


@given(correlation_cases(max_map=80, max_patch=16))
def test_software_backend_is_bit_exact(case):
    terrain, patch, mask, mean_compensation = case
    expected = model.correlate(terrain, patch, mask=mask, mean_compensation=mean_compensation)
    got = correlate(terrain, patch, mask=mask, mean_compensation=mean_compensation, backend="software")
    assert got.dtype == np.int64
    np.testing.assert_array_equal(got, expected)


@given(
    hnp.arrays(np.int16, (90, 150), elements=DEPTH),
    st.integers(10, 20),
    st.integers(10, 20),
    st.booleans(),
)
def test_software_backend_beyond_32_bit_sums(terrain, h, w, mean_compensation):
    """Patches past 16 x 16 spill the kernel's 32-bit lanes into int64 in chunks."""
    patch = terrain[3 : 3 + h, 5 : 5 + w][::-1].copy()
    expected = model.correlate(terrain, patch, mean_compensation=mean_compensation)
    np.testing.assert_array_equal(correlate(terrain, patch, mean_compensation=mean_compensation), expected)


def test_worst_case_16x16_fills_32_unsigned_bits_exactly():
    terrain = np.full((16, 40), 32767, dtype=np.int16)
    terrain[8:, :] = -32768
    patch = np.where(np.arange(16)[:, None] < 8, -32768, 32767).astype(np.int16) * np.ones((1, 16), np.int16)
    expected = model.correlate(terrain, patch)
    assert expected.max() == model.correlator_widths(16, 16).surface.hi > 2**31
    np.testing.assert_array_equal(correlate(terrain, patch), expected)


def test_every_backend_agrees_on_the_papers_size():
    rng = np.random.default_rng(7)
    terrain = rng.integers(-32768, 32768, (501, 501)).astype(np.int16)
    patch = rng.integers(-32768, 32768, (10, 10)).astype(np.int16)
    mask = rng.random((10, 10)) > 0.2
    # The hardware backends have their own tests (tests/host/correlator/test_driver.py, tests/sim/test_device_cosim.py).
    surfaces = {name: correlate(terrain, patch, mask=mask, backend=name) for name in BACKENDS if name not in ("rtl", "fpga")}
    for name, surface in surfaces.items():
        np.testing.assert_array_equal(surface, surfaces["model"], err_msg=name)


def test_kernel_reports_its_instruction_set():
    assert software.KERNEL in {"avx512", "avx2", "generic"}


def test_unknown_backend_is_named():
    with pytest.raises(ValueError, match="unknown correlator backend 'gpu'"):
        correlate(np.zeros((4, 4), np.int16), np.zeros((2, 2), np.int16), backend="gpu")


def test_host_rejects_bad_input_like_the_model():
    with pytest.raises(ValueError, match="integer array"):
        correlate(np.zeros((4, 4)), np.zeros((2, 2), np.int16))
