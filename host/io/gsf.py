"""GSF files: swath bathymetry ping records as pings, decoded by gsfu (every beam array of the record).

gsfu (BSD-2, pure Python, written against libgsf 3.11) decodes each ping's beam arrays with NumPy, all of
them. libgsf's own Python bindings (bluemvmt-gsf) hand a record over as JSON that leaves out the along-track
offsets (in the EX1604 file, up to 755 m: the beams would be misplaced by that) and, in files without a
sensor-specific subrecord, the beam flags; they are kept as the tests' independent decoder of what they do
hand over.

The records' framing (a big-endian size and record identifier each) is walked here first, record by record,
without decoding: the whole records before the first one cut off by the end of the file or not framed as a
GSF record are read, and that damage is counted (gsfu alone refuses a damaged file whole). Memory: gsfu's
index of the records (about 50 bytes a record) and one record at a time.

A ping's position is the record's own; depths are GSF's (below the sea surface, as processed); a beam is
valid when its beam flag is 0 (GSF's flags: bit 0 ignore, bits 1-7 the reasons); GSF's "not available"
heading, roll, pitch and heave (361, 99) read as NaN, and so does the surface sound speed where the
record's sensor-specific subrecord has none (or it is 0).
"""

from __future__ import annotations

import math
import struct
from array import array
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .errors import SurveyFileError
from .survey import Ping

__all__ = ["read_gsf_pings"]

_HEADER_RECORD, _SWATH_BATHYMETRY_PING = 1, 2  # GSF's record identifiers
_RECORD_TYPES = 14  # identifiers 1..13 name GSF's record types
_CHECKSUM_FLAG = 0x80000000  # identifier bit 31: a 4-byte checksum follows the framing
_FRAMING = struct.Struct(">II")  # data size, identifier word
_MAX_RECORD = 1 << 24  # libgsf's largest record (GSF_MAX_RECORD_SIZE)
_NULL = {"Heading_deg": 361.0, "Roll_deg": 99.0, "Pitch_deg": 99.0, "Heave_m": 99.0}  # GSF_NULL_*: not available


def read_gsf_pings(path: Path, skipped: Counter, notes: Counter) -> Iterator[Ping]:
    """Pings of one GSF file, in file order; a damaged or cut-off record ends the file and is counted."""
    from GSFU.gsfu import RecordType, gsf

    index, version = _whole_records(path, skipped)
    reader = gsf(str(path))
    reader.OpenFiletoRead()
    try:
        # gsfu's documented index (one row per record) and version, built from the walk: only the whole records.
        reader.Index, reader.gsfVersion = index, version
        records = reader.iter_records(RecordType.GSF_RECORD_SWATH_BATHYMETRY_PING)
        while True:
            try:
                _, _, record = next(records)
            except StopIteration:
                break
            except (struct.error, IndexError, ValueError, KeyError) as error:
                skipped[f"{path.name}: the file's remainder after a ping record gsfu cannot decode ({error})"] += 1
                break
            ping = _ping(path, record, skipped, notes)
            if ping is not None:
                yield ping
    finally:
        reader.closeFile()


def _whole_records(path: Path, skipped: Counter):
    """gsfu's record index (a DataFrame) of the whole records before any damage, and the file's GSF version."""
    import pandas as pd

    size = path.stat().st_size
    offsets, sizes, words = array("q"), array("q"), array("q")
    version = None
    with path.open("rb") as f:
        at = 0
        while at < size:
            framing = f.read(_FRAMING.size)
            if len(framing) < _FRAMING.size:
                skipped[f"{path.name}: a record cut off by the end of the file ({size - at} bytes)"] += 1
                break
            data_size, word = _FRAMING.unpack(framing)
            record_id = word & 0x003FFFFF
            read_size = data_size + (4 if word & _CHECKSUM_FLAG else 0)
            if not (1 <= record_id < _RECORD_TYPES and 8 < read_size <= _MAX_RECORD):
                skipped[f"{path.name}: bytes that are no GSF record at byte {at} (the file's remainder not read)"] += 1
                break
            if at + _FRAMING.size + read_size > size:
                skipped[f"{path.name}: a record cut off by the end of the file ({size - at} of {_FRAMING.size + read_size} bytes)"] += 1
                break
            if record_id == _HEADER_RECORD and version is None:
                f.seek(at + _FRAMING.size + read_size - data_size)
                version = f.read(min(data_size, 12)).split(b"\x00", 1)[0].decode("ascii", "replace")
            offsets.append(at)
            sizes.append(data_size)
            words.append(word)
            at += _FRAMING.size + read_size
            f.seek(at)
    if version is None:
        raise SurveyFileError(f"{path.name} has no GSF header record before its first damage: not readable as GSF")
    words_array = np.array(words, dtype=np.int64)
    ids = words_array & 0x003FFFFF
    checksum = (words_array & _CHECKSUM_FLAG) != 0
    sizes_array = np.array(sizes, dtype=np.int64)
    index = pd.DataFrame({"RecordType": pd.Categorical(ids), "RecordID": ids, "ByteOffset": np.array(offsets, dtype=np.int64),
                          "RecordSize": sizes_array, "TotalBytes": _FRAMING.size + sizes_array + np.where(checksum, 4, 0),
                          "ChecksumFlag": checksum})
    return index, version


def _ping(path: Path, record: dict, skipped: Counter, notes: Counter) -> Ping | None:
    beams = record.get("Beams") or {}
    depth, across = beams.get("Depth_m"), beams.get("AcrossTrack_m")
    if depth is None or across is None:
        skipped[f"{path.name}: ping record without depth or across-track arrays"] += 1
        return None
    n = len(depth)
    along = beams.get("AlongTrack_m")
    if along is None:
        notes[f"{path.name}: ping records without along-track offsets (taken as 0)"] += 1
        along = np.zeros(n)
    flags = beams.get("BeamFlags")
    if flags is None:
        notes[f"{path.name}: ping records without beam flags (every beam taken as valid)"] += 1
        flags = np.zeros(n, dtype=np.int64)
    scalar = {key: float(record[key]) if float(record[key]) != null else math.nan for key, null in _NULL.items()}
    sound_speed = float((record.get("SensorSpecific") or {}).get("SurfaceVelocity_mps") or 0.0)
    return Ping(
        time_s=_posix(record["PingTime"]), lat_deg=float(record["Latitude_deg"]), lon_deg=float(record["Longitude_deg"]),
        heading_deg=scalar["Heading_deg"], roll_deg=scalar["Roll_deg"], pitch_deg=scalar["Pitch_deg"], heave_m=scalar["Heave_m"],
        sound_speed_mps=sound_speed if sound_speed > 0 else math.nan,
        along_m=np.asarray(along, dtype=np.float64), across_m=np.asarray(across, dtype=np.float64),
        depth_m=np.asarray(depth, dtype=np.float64), valid=np.asarray(flags) == 0,
    )


def _posix(value) -> float:
    """POSIX seconds of gsfu's ping time (an ISO 8601 string with its zone, or already seconds)."""
    if isinstance(value, int | float):
        return float(value)
    import datetime as dt

    return dt.datetime.fromisoformat(str(value)).timestamp()
