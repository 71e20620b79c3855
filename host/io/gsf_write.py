"""Writing pings as GSF: swath bathymetry ping records through gsfu, read back by :mod:`lost.host.io.gsf`.

gsfu (BSD-2, pure Python, written against libgsf 3.11's encoder) is the maintained library that writes GSF;
libgsf's own Python bindings (bluemvmt-gsf) only decode. The tests read a file written here with the
reference C library too (``tests/host/io/test_gsf.py``), so the two implementations check each other.

Per ping: the time (seconds and nanoseconds), latitude and longitude (1e-7 degree), heading, roll, pitch
(0.01 degree) and heave (1 cm), GSF's "not available" where a value is NaN; per beam the depth below the
water line (1 mm), the across- and along-track offsets (1 mm, finer than gsfu's 1 cm default) and the beam
flag (0 valid, 1 GSF's "ignore" bit). A beam whose depth or offsets are not finite is written with zeros and
flagged, as GSF has no NaN; a negative depth (above the water line) cannot be written and is refused. The
sound speed at the transducer lives in GSF's vendor-specific subrecords and is not written (it reads back
NaN, as in GSF files without one), nor is the transducer's depth (GSF's depths are below the surface already).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from .survey import Ping

__all__ = ["write_gsf_pings"]

_IGNORE_BEAM = 0x01  # GSF beam flag bit 0: the beam is not to be used
_ACROSS_TRACK, _ALONG_TRACK = 2, 3  # GSF's beam array subrecord ids
_MILLIMETRE_SIGNED = (1000.0, 0.0, 4, True)  # multiplier, offset, bytes, signed: +-2,147 km to 1 mm


def write_gsf_pings(pings: Iterable[Ping], path: str | os.PathLike) -> Path:
    """Write pings as a GSF file (a header record, then one swath bathymetry ping record per ping); returns the path.

    Streamed, one ping at a time; the file is written whole to ``NAME.partial``, then renamed. A ping without
    position or heading, or with a beam above the water line, raises ``ValueError`` naming it, and no file is left.
    """
    from GSFU.gsfu import DEFAULT_PING_SCALE_FACTORS, gsf

    path = Path(path)
    partial = path.with_name(path.name + ".partial")
    scale = {**DEFAULT_PING_SCALE_FACTORS, _ACROSS_TRACK: _MILLIMETRE_SIGNED, _ALONG_TRACK: _MILLIMETRE_SIGNED}
    out = gsf(str(partial))
    try:
        out.OpenFiletoWrite()
        out.write_header()
        for number, ping in enumerate(pings):
            out.write_swath_bathymetry_ping(_record(ping, number), scale_factors=scale)
        out.closeFile()
        os.replace(partial, path)
    finally:
        out.closeFile()
        partial.unlink(missing_ok=True)
    return path


def _record(ping: Ping, number: int) -> dict:
    from GSFU.gsfu import new_swath_bathymetry_ping

    if not (math.isfinite(ping.lat_deg) and math.isfinite(ping.lon_deg) and math.isfinite(ping.heading_deg)):
        raise ValueError(f"ping {number} at t={ping.time_s} has no position or heading; a GSF ping needs both")
    finite = np.isfinite(ping.depth_m) & np.isfinite(ping.across_m) & np.isfinite(ping.along_m)
    if np.any(finite & (ping.depth_m < 0)):
        k = int(np.flatnonzero(finite & (ping.depth_m < 0))[0])
        raise ValueError(f"ping {number} at t={ping.time_s}: beam {k} is {-ping.depth_m[k]:.2f} m above the water line; GSF depths are unsigned")
    record = new_swath_bathymetry_ping()
    record.update(PingTime=ping.time_s, Longitude_deg=ping.lon_deg, Latitude_deg=ping.lat_deg, NumberBeams=ping.beams,
                  Heading_deg=ping.heading_deg % 360.0)
    for key, value in (("Roll_deg", ping.roll_deg), ("Pitch_deg", ping.pitch_deg), ("Heave_m", ping.heave_m)):
        if math.isfinite(value):
            record[key] = value  # else the template's "not available"
    record["Beams"] = {
        "Depth_m": np.where(finite, ping.depth_m, 0.0), "AcrossTrack_m": np.where(finite, ping.across_m, 0.0),
        "AlongTrack_m": np.where(finite, ping.along_m, 0.0),
        "BeamFlags": np.where(finite & ping.valid, 0, _IGNORE_BEAM).astype(np.uint8),
    }
    return record
