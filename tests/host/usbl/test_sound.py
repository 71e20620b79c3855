"""Sound speed from casts: TEOS-10 against an independent equation, the cast reader's errors, the layers."""

from importlib import resources
from pathlib import Path

import gsw
import numpy as np
import pytest

from lost.host.usbl.sound import SoundSpeedProfile, read_cast, sound_speed_teos10

SHIPPED_CAST = Path(str(resources.files("lost.host.usbl") / "data" / "scs_june.csv"))


def mackenzie_1981(temperature_c, salinity, depth_m):
    """Mackenzie's nine-term sound speed equation (JASA 70, 1981), independent of TEOS-10."""
    t, s, d = temperature_c, salinity, depth_m
    return (1448.96 + 4.591 * t - 5.304e-2 * t**2 + 2.374e-4 * t**3 + 1.340 * (s - 35) + 1.630e-2 * d + 1.675e-7 * d**2
            - 1.025e-2 * t * (s - 35) - 7.139e-13 * t * d**3)


@pytest.mark.parametrize(("temperature", "salinity", "depth"), [(25.0, 35.0, 0.0), (10.0, 34.5, 300.0), (4.0, 34.6, 1000.0), (2.0, 34.7, 3000.0)])
def test_teos10_speed_agrees_with_mackenzie(temperature, salinity, depth):
    pressure = gsw.p_from_z(-depth, 20.0)
    speed = sound_speed_teos10(pressure, temperature, salinity, 20.0, 115.0)
    assert speed == pytest.approx(mackenzie_1981(temperature, salinity, depth), abs=0.5)


def _write(tmp_path, text, name="cast.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_depth_pressure_and_conductivity_give_the_same_speeds(tmp_path):
    depth = np.array([2.0, 50.0, 400.0, 1000.0])
    temperature = np.array([28.0, 25.0, 9.0, 4.5])
    salinity = np.array([33.8, 34.3, 34.4, 34.55])
    pressure = gsw.p_from_z(-depth, 18.0)
    conductivity = gsw.C_from_SP(salinity, temperature, pressure)
    header = "# latitude = 18.0\n# longitude = 115.5\n"
    by_depth = read_cast(_write(tmp_path, header + "depth_m,temperature_c,salinity_psu\n"
                                + "".join(f"{a},{b},{c}\n" for a, b, c in zip(depth, temperature, salinity)), "a.csv"))
    by_pressure = read_cast(_write(tmp_path, header + "pressure_dbar,temperature_c,conductivity_ms_cm\n"
                                   + "".join(f"{float(a)!r},{b},{float(c)!r}\n" for a, b, c in zip(pressure, temperature, conductivity)), "b.csv"))
    np.testing.assert_allclose(by_pressure.depth_m, depth, atol=1e-6)
    np.testing.assert_allclose(by_pressure.sound_speed_m_s, by_depth.sound_speed_m_s, atol=1e-6)
    assert by_depth.latitude_deg == 18.0 and by_depth.longitude_deg == 115.5


def test_a_sound_velocity_probe_cast_is_taken_as_is(tmp_path):
    cast = read_cast(_write(tmp_path, "depth_m,sound_speed_m_s\n0,1540\n100,1530\n"), latitude_deg=10.0, longitude_deg=0.0)
    np.testing.assert_array_equal(cast.sound_speed_m_s, [1540.0, 1530.0])


@pytest.mark.parametrize(("text", "message"), [
    ("depth_m,temperature_c\n0,20\n10,19\n", "neither salinity_psu nor conductivity_ms_cm"),
    ("temperature_c,salinity_psu\n20,35\n19,35\n", "no depth_m or pressure_dbar"),
    ("depth_m,temperature_c,salinity_psu\n0,20,35\n10,abc,35\n", "column 'temperature_c' .* data row 2"),
    ("depth_m,temperature_c,salinity_psu\n0,20,35\n0,19,35\n", "must increase strictly .* data row 2"),
    ("depth_m,temperature_c,salinity_psu\n0,20,35\n10,60,35\n", "temperature_c 60.000 at data row 2"),
    ("depth_m,temperature_c,salinity_psu\n0,20,35\n", "at least two samples"),
])
def test_bad_casts_name_the_problem(tmp_path, text, message):
    with pytest.raises(ValueError, match=message):
        read_cast(_write(tmp_path, "# latitude = 1\n# longitude = 2\n" + text))


def test_a_cast_without_position_is_refused(tmp_path):
    with pytest.raises(ValueError, match="position is unknown"):
        read_cast(_write(tmp_path, "depth_m,temperature_c,salinity_psu\n0,20,35\n10,19,35\n"))
    with pytest.raises(FileNotFoundError):
        read_cast(tmp_path / "missing.csv")


def test_shipped_cast_and_its_layers():
    cast = read_cast(SHIPPED_CAST)
    assert cast.depth_m[-1] == 1500.0
    assert 1540.0 < cast.sound_speed_m_s[0] < 1546.0 and 1480.0 < cast.sound_speed_m_s.min() < 1486.0
    full = SoundSpeedProfile.from_cast(cast)
    thin = SoundSpeedProfile.from_cast(cast, tolerance_m_s=0.5)
    assert thin.depth_m.size < full.depth_m.size / 2
    assert np.max(np.abs(thin.speed_at(cast.depth_m) - cast.sound_speed_m_s)) <= 0.5
    with pytest.raises(ValueError, match="below the profile's last sample"):
        full.speed_at(1600.0)


def test_harmonic_mean_of_a_linear_profile():
    profile = SoundSpeedProfile(np.array([0.0, 1000.0]), np.array([1500.0, 1480.0]))
    expected = 1000.0 / (1000.0 / 20.0 * np.log(1500.0 / 1480.0))
    assert profile.harmonic_mean_m_s(0.0, 1000.0) == pytest.approx(expected, rel=1e-12)
