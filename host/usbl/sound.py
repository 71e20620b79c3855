"""Sound speed from CTD casts (TEOS-10 through ``gsw``) and the profile cut into constant-gradient layers.

The cast CSV (one header line naming the columns; ``#`` lines are comments, and ``# latitude = 18.5`` /
``# longitude = 115.0`` lines give the cast's position):

============================  =========================================================
column                        meaning
============================  =========================================================
``depth_m`` or                depth below the sea surface, metres, positive down; or sea
``pressure_dbar``             pressure (absolute minus 10.1325 dbar), dbar
``temperature_c``             in-situ temperature, deg C (ITS-90)
``salinity_psu`` or           Practical Salinity (PSS-78); or conductivity, mS/cm;
``conductivity_ms_cm`` or     or conductivity, S/m (converted: 1 S/m = 10 mS/cm)
``conductivity_s_m``
``sound_speed_m_s``           (instead of temperature and salinity) a sound-velocity probe's speed
============================  =========================================================

Column names are case-blind (``DEPTH_M`` is ``depth_m``), so a file holding both is refused; the file must be UTF-8
(ASCII is); a conductivity column whose values are S/m under the mS/cm name (seawater is 20-70 mS/cm, 2-7 S/m) is
refused with the salinities both readings give.

The TEOS-10 chain: ``SP = gsw.SP_from_C(C, t, p)`` (only from conductivity), ``SA = gsw.SA_from_SP(SP, p, lon, lat)``,
``CT = gsw.CT_from_t(SA, t, p)``, ``c = gsw.sound_speed(SA, CT, p)``; depth and pressure convert with
``gsw.p_from_z(-depth, lat)`` and ``-gsw.z_from_p(p, lat)``.
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass
from pathlib import Path

import gsw
import numpy as np
import pandas as pd

__all__ = ["Cast", "CastError", "SoundSpeedProfile", "read_cast", "sound_speed_teos10", "cast_from_table", "extend_cast"]


class CastError(ValueError):
    """A cast file that cannot be read as a seawater cast; the message names the file and the problem."""


_POSITION = re.compile(r"^#\s*(latitude|longitude)\s*[=:]\s*([-+0-9.eE]+)\s*$")


@dataclass(frozen=True)
class Cast:
    """One CTD or SVP cast: depth (m, increasing) and sound speed (m/s) at each sample.

    ``temperature_c`` and ``salinity_psu`` are NaN for a sound-velocity probe's cast.
    """

    depth_m: np.ndarray
    sound_speed_m_s: np.ndarray
    temperature_c: np.ndarray
    salinity_psu: np.ndarray
    latitude_deg: float
    longitude_deg: float
    source: str = ""


def sound_speed_teos10(pressure_dbar, temperature_c, practical_salinity, latitude_deg: float, longitude_deg: float) -> np.ndarray:
    """Sound speed (m/s) of seawater by TEOS-10: ``gsw.sound_speed`` on Absolute Salinity and Conservative Temperature.

    Parameters
    ----------
    pressure_dbar : array_like
        Sea pressure, dbar.
    temperature_c : array_like
        In-situ temperature (ITS-90), deg C.
    practical_salinity : array_like
        Practical Salinity (PSS-78).
    latitude_deg, longitude_deg : float
        Position of the cast (Absolute Salinity depends on it through the salinity anomaly atlas).
    """
    p = np.asarray(pressure_dbar, dtype=float)
    sa = gsw.SA_from_SP(np.asarray(practical_salinity, dtype=float), p, longitude_deg, latitude_deg)
    ct = gsw.CT_from_t(sa, np.asarray(temperature_c, dtype=float), p)
    return np.asarray(gsw.sound_speed(sa, ct, p), dtype=float)


def _read_position(text: str) -> dict[str, float]:
    found: dict[str, float] = {}
    for line in text.splitlines():
        if line.startswith("#"):
            match = _POSITION.match(line.strip())
            if match:
                found[match.group(1)] = float(match.group(2))
    return found


def _read_text(path: Path) -> str:
    """The file as UTF-8 text (a byte-order mark dropped); another encoding is refused at its first foreign byte."""
    data = path.read_bytes()
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        line = data[: error.start].count(b"\n") + 1
        raise CastError(f"cast file {path}: line {line} is not UTF-8 (byte 0x{data[error.start]:02x}; a Latin-1 or Windows "
                        "degree sign or accent?): save the file as UTF-8") from None


def read_cast(path: str | Path, *, latitude_deg: float | None = None, longitude_deg: float | None = None,
              default_position: tuple[float, float] | None = None) -> Cast:
    """Read a CTD or SVP cast CSV (layout in the module docstring) into a :class:`Cast`.

    The position is ``latitude_deg``/``longitude_deg`` if given, else the file's ``# latitude``/``# longitude``
    lines, else ``default_position`` (e.g. the ship's first position in the log).

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    CastError
        The file is not UTF-8, a column is missing or doubled, a value is not a number, the depths are not increasing,
        a value is out of the physical range or in the wrong unit, or the position is unknown; the message names the
        file, the column and the row.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"cast file {path} does not exist")
    text = _read_text(path)
    position = _read_position(text)
    fallback = default_position or (None, None)
    latitude = latitude_deg if latitude_deg is not None else position.get("latitude", fallback[0])
    longitude = longitude_deg if longitude_deg is not None else position.get("longitude", fallback[1])
    try:
        table = pd.read_csv(io.StringIO(text), comment="#", skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as error:
        raise CastError(f"cast file {path}: not a readable CSV ({error})") from error
    names = [str(name).strip() for name in table.columns]
    # pandas renames an exact repeat "depth_m" to "depth_m.1"
    lowered = [re.sub(r"\.\d+$", "", name.lower()) if re.sub(r"\.\d+$", "", name) in names else name.lower() for name in names]
    twice = sorted({name for name in lowered if lowered.count(name) > 1})
    if twice:
        spelled = [name for name, low in zip(names, lowered) if low in twice]
        raise CastError(f"cast file {path}: column(s) {twice} appear more than once ({spelled}; names are case-blind): keep one")
    table.columns = lowered
    return cast_from_table(table, latitude_deg=latitude, longitude_deg=longitude, source=str(path))


def _column(table: pd.DataFrame, name: str, source: str) -> np.ndarray:
    values = pd.to_numeric(table[name], errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~np.isfinite(values))
    if bad.size:
        # +2: the header is line 1 and rows count from 0.
        raise CastError(f"cast file {source}: column {name!r} has a missing or non-numeric value at data row {bad[0] + 1} "
                         f"(line {bad[0] + 2} without comments): {table[name].iloc[bad[0]]!r}")
    return values


def cast_from_table(table: pd.DataFrame, *, latitude_deg: float | None, longitude_deg: float | None, source: str = "table") -> Cast:
    """A :class:`Cast` from a table with the cast CSV's columns (see the module docstring)."""
    columns = set(table.columns)
    if latitude_deg is None or longitude_deg is None:
        raise CastError(f"cast file {source}: the cast's position is unknown; add '# latitude = ...' and '# longitude = ...' lines "
                         "or pass latitude_deg= and longitude_deg= (TEOS-10 needs them for pressure and Absolute Salinity)")
    if not -90.0 <= latitude_deg <= 90.0 or not -360.0 <= longitude_deg <= 360.0:
        raise CastError(f"cast file {source}: position latitude {latitude_deg}, longitude {longitude_deg} is out of range")
    if len(table) < 2:
        raise CastError(f"cast file {source}: needs at least two samples, has {len(table)}")
    if "depth_m" in columns:
        depth = _column(table, "depth_m", source)
        pressure = gsw.p_from_z(-depth, latitude_deg)
    elif "pressure_dbar" in columns:
        pressure = _column(table, "pressure_dbar", source)
        depth = -np.asarray(gsw.z_from_p(pressure, latitude_deg), dtype=float)
    else:
        raise CastError(f"cast file {source}: no depth_m or pressure_dbar column (has {sorted(columns)})")
    if np.any(depth < 0.0):
        row = int(np.flatnonzero(depth < 0.0)[0]) + 1
        raise CastError(f"cast file {source}: negative depth {depth[row - 1]:.2f} m at data row {row} (depth is positive down)")
    steps = np.diff(depth)
    if np.any(steps <= 0.0):
        row = int(np.flatnonzero(steps <= 0.0)[0]) + 2
        raise CastError(f"cast file {source}: depths must increase strictly (down cast only); data row {row} is at "
                         f"{depth[row - 1]:.2f} m after {depth[row - 2]:.2f} m")
    nan = np.full(depth.shape, np.nan)
    if "temperature_c" in columns:
        temperature = _column(table, "temperature_c", source)
        if "salinity_psu" in columns:
            salinity = _column(table, "salinity_psu", source)
        elif "conductivity_ms_cm" in columns or "conductivity_s_m" in columns:
            salinity = _salinity_from_conductivity(table, temperature, pressure, source)
        else:
            raise CastError(f"cast file {source}: has temperature_c but neither salinity_psu nor conductivity_ms_cm (or conductivity_s_m)")
        _check_range(source, "temperature_c", temperature, -3.0, 40.0)
        _check_range(source, "salinity (practical)", salinity, 2.0, 42.0)
        speed = sound_speed_teos10(pressure, temperature, salinity, latitude_deg, longitude_deg)
    elif "sound_speed_m_s" in columns:
        speed = _column(table, "sound_speed_m_s", source)
        temperature, salinity = nan, nan
    else:
        raise CastError(f"cast file {source}: no temperature_c (with salinity_psu or conductivity_ms_cm) and no sound_speed_m_s column")
    _check_range(source, "sound speed", speed, 1400.0, 1650.0)
    return Cast(depth, speed, temperature, salinity, float(latitude_deg), float(longitude_deg), source)


def _salinity_from_conductivity(table: pd.DataFrame, temperature: np.ndarray, pressure: np.ndarray, source: str) -> np.ndarray:
    """Practical Salinity from a conductivity column in mS/cm or S/m; S/m values under the mS/cm name are refused."""
    if "conductivity_s_m" in table.columns:
        if "conductivity_ms_cm" in table.columns:
            raise CastError(f"cast file {source}: has both conductivity_ms_cm and conductivity_s_m; keep one")
        return np.asarray(gsw.SP_from_C(10.0 * _column(table, "conductivity_s_m", source), temperature, pressure), dtype=float)
    conductivity = _column(table, "conductivity_ms_cm", source)
    salinity = np.asarray(gsw.SP_from_C(conductivity, temperature, pressure), dtype=float)
    as_s_m = np.asarray(gsw.SP_from_C(10.0 * conductivity, temperature, pressure), dtype=float)
    # Seawater conducts 20-70 mS/cm; S/m figures (2-7) read as mS/cm give a salinity of a few units, fresh water at sea.
    if np.nanmax(conductivity) < 10.0 and np.all((as_s_m >= 2.0) & (as_s_m <= 42.0)):
        raise CastError(f"cast file {source}: conductivity_ms_cm runs {conductivity.min():.3f} to {conductivity.max():.3f}: as mS/cm that is a "
                        f"practical salinity of {salinity.min():.2f} to {salinity.max():.2f}, as S/m {as_s_m.min():.2f} to {as_s_m.max():.2f}; "
                        "the values are S/m: name the column conductivity_s_m")
    return salinity


#: Deep water where a cast gives no temperature and salinity (a sound-velocity probe's): its speed's growth with pressure.
DEEP_WATER_SA_G_KG, DEEP_WATER_CT_C = 34.9, 2.0


def extend_cast(cast: Cast, depth_m: float, step_m: float = 25.0) -> Cast:
    """The cast continued from its last sample down to ``depth_m`` (a deep-ocean gradient from TEOS-10).

    Below a cast's last sample the water is taken to keep that sample's temperature and salinity (deep water changes
    slowly), so the speed grows with pressure alone: ``gsw.sound_speed`` at the last Absolute Salinity and
    Conservative Temperature, about 0.017 m/s per metre. A sound-velocity probe's cast (no temperature or salinity)
    gets the same pressure term of deep water (``DEEP_WATER_SA_G_KG``, ``DEEP_WATER_CT_C``) added to its last speed.
    A cast already reaching ``depth_m`` is returned as it is.
    """
    bottom = float(cast.depth_m[-1])
    if depth_m <= bottom:
        return cast
    added = np.append(np.arange(bottom + step_m, depth_m, step_m), depth_m)
    pressure = gsw.p_from_z(-np.append(bottom, added), cast.latitude_deg)
    if np.isfinite(cast.temperature_c[-1]) and np.isfinite(cast.salinity_psu[-1]):
        sa = gsw.SA_from_SP(cast.salinity_psu[-1], pressure[0], cast.longitude_deg, cast.latitude_deg)
        ct = gsw.CT_from_t(sa, cast.temperature_c[-1], pressure[0])
        speed = np.asarray(gsw.sound_speed(sa, ct, pressure[1:]), dtype=float)
        speed += cast.sound_speed_m_s[-1] - float(gsw.sound_speed(sa, ct, pressure[0]))  # continuous at the last sample
        temperature = np.asarray(gsw.t_from_CT(sa, ct, pressure[1:]), dtype=float)
        salinity = np.full(added.shape, cast.salinity_psu[-1])
    else:
        deep = np.asarray(gsw.sound_speed(DEEP_WATER_SA_G_KG, DEEP_WATER_CT_C, pressure), dtype=float)
        speed = cast.sound_speed_m_s[-1] + deep[1:] - deep[0]
        temperature = salinity = np.full(added.shape, np.nan)
    return Cast(np.append(cast.depth_m, added), np.append(cast.sound_speed_m_s, speed), np.append(cast.temperature_c, temperature),
                np.append(cast.salinity_psu, salinity), cast.latitude_deg, cast.longitude_deg, cast.source)


def _check_range(source: str, name: str, values: np.ndarray, low: float, high: float) -> None:
    outside = np.flatnonzero((values < low) | (values > high))
    if outside.size:
        row = int(outside[0])
        raise CastError(f"cast file {source}: {name} {values[row]:.3f} at data row {row + 1} is outside the seawater range [{low}, {high}]")


@dataclass(frozen=True)
class SoundSpeedProfile:
    """Sound speed as layers of constant gradient: ``speed_m_s[i]`` at ``depth_m[i]``, linear in between.

    Above the first depth the speed is held at its first value (the surface mixed layer a cast rarely samples);
    below the last depth the profile is undefined and a ray asked to go there is an error.
    """

    depth_m: np.ndarray
    speed_m_s: np.ndarray

    def __post_init__(self) -> None:
        depth = np.asarray(self.depth_m, dtype=float)
        speed = np.asarray(self.speed_m_s, dtype=float)
        if depth.ndim != 1 or depth.shape != speed.shape or depth.size < 1:
            raise ValueError(f"a profile needs matching 1-D depths and speeds, got shapes {depth.shape} and {speed.shape}")
        if depth.size > 1 and np.any(np.diff(depth) <= 0.0):
            raise ValueError("a profile's depths must increase strictly")
        if not (np.all(np.isfinite(speed)) and np.all(speed > 0.0)):
            raise ValueError("a profile's sound speeds must be finite and positive")
        object.__setattr__(self, "depth_m", depth)
        object.__setattr__(self, "speed_m_s", speed)

    @classmethod
    def from_cast(cls, cast: Cast, *, tolerance_m_s: float = 0.0) -> SoundSpeedProfile:
        """Layers through the cast's samples; with ``tolerance_m_s`` > 0, only the samples needed to keep every
        dropped sample within that speed of the layer through it (Douglas-Peucker on speed against depth)."""
        keep = _simplify(cast.depth_m, cast.sound_speed_m_s, tolerance_m_s) if tolerance_m_s > 0.0 else slice(None)
        return cls(cast.depth_m[keep], cast.sound_speed_m_s[keep])

    @classmethod
    def isovelocity(cls, speed_m_s: float, bottom_m: float = 12000.0) -> SoundSpeedProfile:
        """A constant speed from the surface to ``bottom_m``."""
        return cls(np.array([0.0, bottom_m]), np.array([speed_m_s, speed_m_s]))

    @property
    def bottom_m(self) -> float:
        return float(self.depth_m[-1])

    def speed_at(self, depth_m) -> np.ndarray:
        """Sound speed at the given depths (held constant above the first sample)."""
        depth = np.asarray(depth_m, dtype=float)
        if np.any(depth > self.bottom_m + 1e-9):
            raise ValueError(f"depth {float(np.max(depth)):.2f} m is below the profile's last sample at {self.bottom_m:.2f} m")
        return np.interp(depth, self.depth_m, self.speed_m_s)

    def layers(self, top_m: float, bottom_m: float) -> tuple[np.ndarray, np.ndarray]:
        """Boundaries and speeds of the constant-gradient layers between two depths (both included)."""
        if not bottom_m > top_m:
            raise ValueError(f"the layers' bottom {bottom_m} m must be below their top {top_m} m")
        inside = (self.depth_m > top_m) & (self.depth_m < bottom_m)
        depth = np.concatenate(([top_m], self.depth_m[inside], [bottom_m]))
        return depth, self.speed_at(depth)

    def harmonic_mean_m_s(self, top_m: float, bottom_m: float) -> float:
        """The speed that gives a vertical ray's travel time between two depths."""
        depth, speed = self.layers(top_m, bottom_m)
        dz, c0, c1 = np.diff(depth), speed[:-1], speed[1:]
        gradient = (c1 - c0) / dz
        time = dz * _log1p_ratio(gradient * dz / c0) / c0
        return float((bottom_m - top_m) / time.sum())


def _log1p_ratio(x: np.ndarray) -> np.ndarray:
    """log1p(x) / x, continued to 1 at x = 0 (an isovelocity layer is the limit of a constant-gradient one)."""
    x = np.asarray(x, dtype=float)
    small = np.abs(x) < 1e-8
    safe = np.where(small, 1.0, x)
    return np.where(small, 1.0 - x / 2.0 + x * x / 3.0, np.log1p(safe) / safe)


def _simplify(depth: np.ndarray, speed: np.ndarray, tolerance: float) -> np.ndarray:
    keep = np.zeros(depth.size, dtype=bool)
    keep[[0, -1]] = True
    stack = [(0, depth.size - 1)]
    while stack:
        first, last = stack.pop()
        if last - first < 2:
            continue
        inner = slice(first + 1, last)
        line = np.interp(depth[inner], depth[[first, last]], speed[[first, last]])
        worst = int(np.argmax(np.abs(speed[inner] - line)))
        if abs(speed[inner][worst] - line[worst]) > tolerance:
            split = first + 1 + worst
            keep[split] = True
            stack += [(first, split), (split, last)]
    return keep
