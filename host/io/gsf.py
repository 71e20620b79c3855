"""GSF files: swath bathymetry ping records as pings, through libgsf (the format's reference library).

bluemvmt-gsf bundles libgsf 3.11 and hands each record over as JSON, one record at a time, so memory stays
bounded. A ping's position is the record's own; depths are GSF's (below the sea surface, as processed);
along-track offsets absent from a record are taken as 0 and counted in the notes; a beam is valid when
its beam flag is 0 (GSF's flags: bit 0 ignore, bits 1-7 the reasons).
"""

from __future__ import annotations

import json
import math
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .errors import SurveyFileError
from .survey import Ping

__all__ = ["read_gsf_pings"]

_SWATH_BATHYMETRY_PING = 2  # libgsf's GSF_RECORD_SWATH_BATHYMETRY_PING
_END_OF_FILE = -23  # libgsf's GSF_READ_TO_END_OF_FILE: the file ended where a record could begin
_NO_VALUE = 0.0  # GSF writes 0 where a ping attribute (the surface sound speed) was not recorded


def read_gsf_pings(path: Path, skipped: Counter, notes: Counter) -> Iterator[Ping]:
    """Pings of one GSF file, in file order; records libgsf cannot decode end the file and are counted."""
    from bluemvmt_gsf.libgsf import GsfException, GsfFile

    try:
        gsf = GsfFile(path)
    except GsfException as error:
        raise SurveyFileError(f"{path.name} cannot be opened as GSF ({error})") from None
    with gsf:
        try:
            for raw in gsf.next_json_record():
                record = json.loads(raw)
                if record.get("record_type") != _SWATH_BATHYMETRY_PING:
                    continue
                ping = _ping(path, record["json_record"], skipped, notes)
                if ping is not None:
                    yield ping
        except GsfException as error:
            # libgsf stops at the first record it cannot read (a cut-off or damaged record): the rest is lost.
            skipped[f"{path.name}: the file's remainder after a record libgsf cannot read ({error})"] += 1
        if gsf.gsf.gsfIntError() != _END_OF_FILE:
            # The record iterator ends quietly on any error; libgsf's last error tells a cut-off record from the end.
            skipped[f"{path.name}: the file's remainder after a record libgsf cannot read ({gsf.gsf.gsfStringError().decode(errors='replace')})"] += 1


def _ping(path: Path, body: dict, skipped: Counter, notes: Counter) -> Ping | None:
    depth, across = body.get("depth"), body.get("across_track")
    if depth is None or across is None:
        skipped[f"{path.name}: ping record without depth or across-track arrays"] += 1
        return None
    n = len(depth)
    along = body.get("along_track")
    if along is None:
        notes[f"{path.name}: ping records without along-track offsets (taken as 0)"] += 1
        along = np.zeros(n)
    flags = body.get("beam_flags")
    if flags is None:
        notes[f"{path.name}: ping records without beam flags (every beam taken as valid)"] += 1
        flags = np.zeros(n, dtype=np.int64)
    sensor = body.get("sensor_data") or {}
    sound_speed = float(sensor.get("surface_velocity", _NO_VALUE) or _NO_VALUE)
    return Ping(
        time_s=float(body["ping_time"]), lat_deg=float(body.get("latitude", math.nan)), lon_deg=float(body.get("longitude", math.nan)),
        heading_deg=float(body["heading"]), roll_deg=float(body["roll"]), pitch_deg=float(body["pitch"]), heave_m=float(body["heave"]),
        sound_speed_mps=sound_speed if sound_speed != _NO_VALUE else math.nan,
        along_m=np.asarray(along, dtype=np.float64), across_m=np.asarray(across, dtype=np.float64),
        depth_m=np.asarray(depth, dtype=np.float64), valid=np.asarray(flags) == 0,
    )
