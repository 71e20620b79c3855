import numpy as np
import pytest

from lost.host.records import NavRecords, SonarPatch

FIELDS = ["ship_x_m", "ship_y_m", "ship_heading_deg", "vehicle_depth_m", "altitude_m", "vel_x_mps", "vel_y_mps", "slant_range_m", "cable_out_m"]


def _records(**override):
    values = {"t_s": np.arange(4.0)} | {name: np.zeros(4) for name in FIELDS}
    return NavRecords(**(values | override))


def test_valid_records():
    records = _records(truth_x_m=np.ones(4), truth_y_m=np.ones(4))
    assert len(records) == 4 and records.has_truth


def test_time_going_backwards_is_located():
    with pytest.raises(ValueError, match=r"record 2: t=0.5 s after 1.0 s"):
        _records(t_s=np.array([0.0, 1.0, 0.5, 3.0]))


def test_length_mismatch_is_named():
    with pytest.raises(ValueError, match=r"altitude_m has shape \(3,\)"):
        _records(altitude_m=np.zeros(3))


def test_half_truth_is_refused():
    with pytest.raises(ValueError, match="together"):
        _records(truth_x_m=np.zeros(4))


def test_sonar_patch_centre_offset_is_two_finite_metres():
    assert SonarPatch(np.zeros((2, 2)), 10.0).centre_offset_m == (0.0, 0.0)
    assert SonarPatch(np.zeros((2, 2)), 10.0, centre_offset_m=np.array([-3, 40])).centre_offset_m == (-3.0, 40.0)
    for bad in ((1.0,), (0.0, np.nan), (1.0, 2.0, 3.0)):
        with pytest.raises(ValueError, match="centre_offset_m"):
            SonarPatch(np.zeros((2, 2)), 10.0, centre_offset_m=bad)
