import numpy as np
import pytest

from lost.model import dequantize, quantize


def test_rounding_modes():
    depths = np.array([0.125, 0.375, -0.125, 0.3])  # exact binary fractions of the 0.25 m step
    np.testing.assert_array_equal(quantize(depths, 0.25), [0, 2, 0, 1])  # half to even
    np.testing.assert_array_equal(quantize(depths, 0.25, rounding="floor"), [0, 1, -1, 1])
    np.testing.assert_array_equal(quantize(depths, 0.25, rounding="ceil"), [1, 2, 0, 2])


def test_offset_and_round_trip():
    depths = np.array([[1000.0, 1003.2], [996.8, 1000.1]])
    words = quantize(depths, 0.1, offset_m=1000.0)
    assert words.dtype == np.int16
    np.testing.assert_array_equal(words, [[0, 32], [-32, 1]])
    np.testing.assert_allclose(dequantize(words, 0.1, offset_m=1000.0), depths)


def test_full_range_is_usable():
    assert quantize(np.array([-3276.8, 3276.7]), 0.1).tolist() == [-32768, 32767]


def test_overflow_names_the_depth_and_the_range():
    with pytest.raises(ValueError, match=r"overflow.*3276.8.*index \(1,\)"):
        quantize(np.array([0.0, 3276.8]), 0.1)


def test_nan_is_counted_and_located():
    with pytest.raises(ValueError, match=r"2 NaN or infinite.*index \(0, 1\)"):
        quantize(np.array([[1.0, np.nan], [np.inf, 2.0]]), 0.1)


@pytest.mark.parametrize("lsb", [0.0, -0.1, np.nan])
def test_bad_lsb(lsb):
    with pytest.raises(ValueError, match="lsb_m"):
        quantize(np.zeros(3), lsb)


def test_bad_rounding():
    with pytest.raises(ValueError, match="rounding"):
        quantize(np.zeros(3), 0.1, rounding="stochastic")


def test_dequantize_rejects_floats():
    with pytest.raises(ValueError, match="integer"):
        dequantize(np.zeros(3), 0.1)
