"""The simulator's truth ocean beside the cast, and the sound speed's error as the fix and the filter model it."""

from __future__ import annotations

import numpy as np
import pytest

from lost.host.usbl.filter import SOUND, SoundSpeedError
from lost.host.usbl.fix import UsblArray, reply_from_geometry, usbl_fix
from lost.host.usbl.ocean import TruthOcean
from lost.host.usbl.scenario import OceanSpec, load_usbl_scenario, shipped_cast_path
from lost.host.usbl.sound import SoundSpeedProfile, read_cast


@pytest.fixture(scope="module")
def cast():
    return read_cast(shipped_cast_path("scs_june"))


def test_a_still_ocean_is_the_cast_at_its_own_samples(cast):
    ocean = TruthOcean.build(cast, OceanSpec(fine_step_m=10.0), 1200.0)
    profile = ocean.profile_at(900.0)
    np.testing.assert_allclose(profile.speed_at(cast.depth_m), cast.sound_speed_m_s, atol=1e-9)
    assert ocean.profile_at(0.0) is profile


def test_a_cast_that_stops_above_the_tow_is_continued_in_the_truth(cast):
    ocean = TruthOcean.build(cast, OceanSpec(), 2000.0)
    assert ocean.profile_at(0.0).bottom_m >= 2100.0


def test_the_surface_warms_with_the_casts_age_and_the_deep_water_does_not(cast):
    ocean = TruthOcean.build(cast, OceanSpec(cast_age_h=4.0, surface_warming_c_per_h=0.25, warm_layer_m=30.0), 1200.0)
    still = TruthOcean.build(cast, OceanSpec(), 1200.0)
    start, later = ocean.profile_at(0.0), ocean.profile_at(3600.0)
    # 1 degC warmer at the surface is about 2.5-3 m/s faster at 29 degC; 1.25 degC an hour later.
    assert 2.0 < start.speed_at(0.0) - still.profile_at(0.0).speed_at(0.0) < 3.5
    assert later.speed_at(0.0) - start.speed_at(0.0) == pytest.approx(0.25 / 1.0 * (start.speed_at(0.0) - still.profile_at(0.0).speed_at(0.0)),
                                                                       rel=0.05)
    assert abs(start.speed_at(1000.0) - still.profile_at(0.0).speed_at(1000.0)) < 1e-6


def test_internal_waves_heave_the_thermocline_and_come_back(cast):
    ocean = TruthOcean.build(cast, OceanSpec(internal_wave_m=10.0, internal_wave_period_s=1200.0), 1200.0)
    still = TruthOcean.build(cast, OceanSpec(), 1200.0).profile_at(0.0)
    crest = ocean.profile_at(300.0)  # a quarter period: the water at z came from 10 sin(pi z / H) m higher up
    # The heave moves the water, not the pressure: the speed's gradient less its pressure share (about 0.0165 m/s per m).
    gradient = (still.speed_at(405.0) - still.speed_at(395.0)) / 10.0 - 0.0165
    shift = 10.0 * np.sin(np.pi * 400.0 / cast.depth_m[-1])
    assert crest.speed_at(400.0) - still.speed_at(400.0) == pytest.approx(-gradient * shift, rel=0.05)
    np.testing.assert_allclose(ocean.profile_at(1200.0).speed_m_s, still.speed_m_s, atol=1e-9)


def test_a_speed_probe_cast_cannot_change(tmp_path):
    path = tmp_path / "svp.csv"
    path.write_text("# latitude = 18\n# longitude = 115\ndepth_m,sound_speed_m_s\n0,1540\n1000,1485\n")
    with pytest.raises(ValueError, match="svp.csv: a changing truth ocean .* needs the cast's temperature and salinity"):
        TruthOcean.build(read_cast(path), OceanSpec(internal_wave_m=5.0), 800.0)


def test_the_fix_moves_along_its_jacobian_when_the_speed_is_wrong(cast):
    """A fix computed with every speed 1e-4 too high lies J * 1e-4 from the one with the true speeds."""
    array = UsblArray()
    truth = SoundSpeedProfile.from_cast(cast)
    wrong = SoundSpeedProfile(truth.depth_m, truth.speed_m_s * (1.0 + 1e-4))
    geometry = dict(roll_rad=0.0, pitch_rad=0.0, heading_rad=0.3, antenna_north_m=0.0, antenna_east_m=0.0)
    time, phase_x, phase_y = reply_from_geometry(truth, array, **geometry, target_north_m=-600.0, target_east_m=-250.0, target_depth_m=1000.0)
    # The phases convert at the array's speed; keep the direction cosines to change the range alone.
    cosines = (phase_x * array.wavelength_m(float(truth.speed_at(5.0))) / (2 * np.pi * array.baseline_m),
               phase_y * array.wavelength_m(float(truth.speed_at(5.0))) / (2 * np.pi * array.baseline_m))
    right = usbl_fix(truth, array, travel_time_s=time, direction_cosines=cosines, target_depth_m=1000.0, **geometry)
    off = usbl_fix(wrong, array, travel_time_s=time, direction_cosines=cosines, target_depth_m=1000.0, **geometry)
    moved = np.array([off.north_m - right.north_m, off.east_m - right.east_m, 0.0])
    np.testing.assert_allclose(moved, right.sound_speed_jacobian_m * 1e-4, rtol=0.02, atol=2e-3)
    assert np.linalg.norm(moved) > 0.1


def test_the_sound_speed_variance_grows_with_the_casts_age():
    model = SoundSpeedError(sigma_m_s=0.3, drift_m_s_per_h=0.1, age_h=2.0, speed_m_s=1500.0)
    assert model.variance(0.0) == pytest.approx((0.09 + 0.04) / 1500.0**2)
    assert model.variance(3600.0) == pytest.approx((0.09 + 0.09) / 1500.0**2)
    assert SOUND == 15


def test_the_stale_scenario_ships_its_ocean_and_what_the_operator_knows():
    scenario = load_usbl_scenario("usbl_stale_cast")
    assert scenario.ocean.changes() and scenario.ocean.cast_age_h == 4.0
    config = scenario.processing_config()
    assert config.cast_age_h == 4.0 and config.sound_speed_sigma_m_s == 0.5 and config.array == scenario.usbl
