"""Kongsberg ``.kmall`` files: MRZ datagrams as pings, through pykmall (Kongsberg's own datagram layouts, BSD-2).

pykmall reads each MRZ's variable parts (header, partition, common part, ping info, sectors, receiver
info); its soundings, a fixed 120-byte record each, are read as one NumPy array on pykmall's own layout
rather than one dict per sounding (five times faster).

Two passes, one datagram in memory at a time: the first keeps the attitude samples of the SKM datagrams
(roll, pitch, heave, with the sensor's own times; read here as one NumPy array per datagram on pykmall's layout,
the same values as pykmall's dicts, and only of the sensor the datagrams mark active when the file holds several:
the sensor status bit 0); the second yields one ping per MRZ datagram, an MRZ split
into partitions joined first (:mod:`lost.host.io.kmall_parts`, the live receiver's rule). The MRZ carries its
own position (the reference point's latitude and longitude at the ping), heading and sound
speed at the transducer; the per-sounding x/y/z are re the reference point, and z minus the water
level's height re the reference point is the depth below the water line. Only the main soundings are
read (extra detections are not bottom); a sounding is valid when its detection type is normal (0) and
its detection method not "no valid detection" (0).
"""

from __future__ import annotations

import contextlib
import io
import math
import struct
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from .kmall_parts import DROPPED, HEADER, REASONS, MrzJoiner
from .survey import Ping, interpolate_at

__all__ = ["MRZ_SOUNDING", "decode_mrz", "mrz_ping", "read_kmall_pings", "read_mrz", "skm_samples"]

_PARTITION_AT = HEADER.size
_WHOLE = (1).to_bytes(2, "little") * 2  # numOfDgms 1, dgmNum 1: an MRZ of one part

_MAX_ATTITUDE_GAP_S = 1.0
# One MRZ sounding (EMdgmMRZ_sounding_def, 120 bytes): pykmall's own layout "1H8B1H6f2H18f4H", read for all
# soundings at once instead of one dict per sounding.
MRZ_SOUNDING = np.dtype([
    ("soundingIndex", "<u2"), ("txSectorNumb", "u1"), ("detectionType", "u1"), ("detectionMethod", "u1"), ("rejectionInfo1", "u1"),
    ("rejectionInfo2", "u1"), ("postProcessingInfo", "u1"), ("detectionClass", "u1"), ("detectionConfidenceLevel", "u1"),
    ("padding", "<u2"), ("rangeFactor", "<f4"), ("qualityFactor", "<f4"), ("detectionUncertaintyVer_m", "<f4"),
    ("detectionUncertaintyHor_m", "<f4"), ("detectionWindowLength_sec", "<f4"), ("echoLength_sec", "<f4"), ("WCBeamNumb", "<u2"),
    ("WCrange_samples", "<u2"), ("WCNomBeamAngleAlong_deg", "<f4"), ("meanAbsCoeff_dBPerkm", "<f4"), ("reflectivity1_dB", "<f4"),
    ("reflectivity2_dB", "<f4"), ("receiverSensitivityApplied_dB", "<f4"), ("sourceLevelApplied_dB", "<f4"), ("BScalibration_dB", "<f4"),
    ("TVG_dB", "<f4"), ("beamAngleReRx_deg", "<f4"), ("beamAngleCorrection_deg", "<f4"), ("twoWayTravelTime_sec", "<f4"),
    ("twoWayTravelTimeCorrection_sec", "<f4"), ("deltaLatitude_deg", "<f4"), ("deltaLongitude_deg", "<f4"), ("z_reRefPoint_m", "<f4"),
    ("y_reRefPoint_m", "<f4"), ("x_reRefPoint_m", "<f4"), ("beamIncAngleAdj_deg", "<f4"), ("realTimeCleanInfo", "<u2"),
    ("SIstartRange_samples", "<u2"), ("SIcentreSample", "<u2"), ("SInumSamples", "<u2"),
])


# One SKM sample as pykmall reads it: KMbinary (EMdgmSKM_KMbinary_def, 120 bytes: its type, length, version, time,
# status, position, then 21 float32 from the ellipsoid height on) and KMdelayedHeave (12 bytes); the fields read.
_SKM_INFO = struct.Struct("<H2B4H")  # numBytesInfoPart, sensorSystem, sensorStatus, sensorInputFormat, numSamplesArray, numBytesPerSample, ...
_SKM_SAMPLE_FIELDS = {"time_sec": ("<u4", 8), "time_nanosec": ("<u4", 12), "roll_deg": ("<f4", 40), "pitch_deg": ("<f4", 44),
                      "heave_m": ("<f4", 52)}
_SKM_SAMPLE_MIN = 56  # bytes of a sample up to its heave
_SKM_ACTIVE = 0x01  # sensor status bit 0: the sensor chosen as active


def read_kmall_pings(path: Path, skipped: Counter, notes: Counter) -> Iterator[Ping]:
    """Pings of one ``.kmall`` file, in file order; damaged or cut-off datagrams, and split MRZ that cannot be joined
    whole (:mod:`lost.host.io.kmall_parts`), counted in ``skipped``."""
    first_pass = Counter()  # its framing damage is counted by the second pass
    attitude = _attitude(path, first_pass, notes)
    skipped.update({reason: n for reason, n in first_pass.items() if "'SKM'" in reason and "fewer samples" in reason})
    if attitude["t"].size == 0:
        notes[f"{path.name}: no SKM attitude datagram (roll, pitch and heave unknown)"] += 1
    joiner = MrzJoiner()
    for dg in _datagrams(path, "MRZ", skipped, joiner):
        yield mrz_ping(dg, attitude)
    joiner.finish()
    for reason, count in joiner.counts.items():
        if reason in DROPPED:
            skipped[f"{path.name}: {reason}"] += count
        elif reason == REASONS["joined"]:
            notes[f"{path.name}: {reason}"] += count


def _datagrams(path: Path, wanted: str, skipped: Counter, joiner: MrzJoiner | None = None, *, raw: bool = False) -> Iterator:
    """The ``wanted`` datagrams of a file decoded by pykmall (their bytes with ``raw``); an MRZ in partitions goes
    through ``joiner`` and is decoded when whole."""
    from KMALL.kmall import kmall

    reader = kmall(str(path))
    try:
        reader.OpenFiletoRead()
        reader.file_size = path.stat().st_size
        while True:
            at = reader.FID.tell()
            if at + 8 > reader.file_size:
                return
            size = int.from_bytes(reader.FID.read(4), "little")
            name = reader.FID.read(4)
            if not (name[:1] == b"#" and name[1:].isalpha() and name[1:].isupper()) or size < 20:
                skipped[f"{path.name}: bytes that are no datagram where one should start (the file's remainder not read)"] += 1
                return
            if at + size > reader.file_size:
                skipped[f"{path.name}: datagram '{name.decode()}' cut off by the end of the file ({reader.file_size - at} of {size} bytes)"] += 1
                return
            end_size = struct.unpack("<I", _read_at(reader.FID, at + size - 4, 4))[0]
            if end_size != size:
                skipped[f"{path.name}: datagram '{name.decode()}' whose closing length disagrees with its opening one (the file's remainder not read)"] += 1
                return
            reader.FID.seek(at)
            if raw and name[1:].decode() == wanted:
                yield reader.FID.read(size)
            elif name[1:].decode() == wanted:
                try:
                    dg = _decoded(reader, wanted, size, joiner)
                except (struct.error, KeyError, ValueError, IndexError) as error:
                    skipped[f"{path.name}: damaged datagram '{wanted}' ({type(error).__name__})"] += 1
                else:
                    if dg is not None:
                        yield dg
            reader.FID.seek(at + size)
    finally:
        reader.closeFile()


def _decoded(reader, wanted: str, size: int, joiner: MrzJoiner | None) -> dict | None:
    """The datagram at the reader's position, decoded; a part of a split MRZ goes to ``joiner`` (``None`` until whole)."""
    if wanted == "MRZ" and joiner is not None and size >= _PARTITION_AT + 4 and _read_at(reader.FID, reader.FID.tell() + _PARTITION_AT, 4) != _WHOLE:
        whole = joiner.add(reader.FID.read(size))
        return None if whole is None else decode_mrz(whole)
    with contextlib.redirect_stdout(io.StringIO()):  # pykmall prints while it scans
        return read_mrz(reader) if wanted == "MRZ" else getattr(reader, f"read_EMdgm{wanted}")()


def decode_mrz(datagram: bytes) -> dict:
    """One whole MRZ datagram's bytes decoded as :func:`read_mrz` decodes it from a file."""
    from KMALL.kmall import kmall

    reader = kmall(None)
    reader.FID = io.BytesIO(datagram)
    reader.file_size = len(datagram)
    with contextlib.redirect_stdout(io.StringIO()):  # pykmall prints while it scans
        return read_mrz(reader)


def read_mrz(reader) -> dict:
    """pykmall's read_EMdgmMRZ, its parts in its order, with the soundings read as one array."""
    dg = {"header": reader.read_EMdgmHeader(), "partition": reader.read_EMdgmMpartition(), "cmnPart": reader.read_EMdgmMbody(),
          "pingInfo": reader.read_EMdgmMRZ_pingInfo()}
    for _ in range(dg["pingInfo"]["numTxSectors"]):
        reader.read_EMdgmMRZ_txSectorInfo()
    dg["rxInfo"] = rx = reader.read_EMdgmMRZ_rxInfo()
    for _ in range(rx["numExtraDetectionClasses"]):
        reader.read_EMdgmMRZ_extraDetClassInfo()
    count = rx["numSoundingsMaxMain"] + rx["numExtraDetections"]
    if rx["numBytesPerSounding"] != MRZ_SOUNDING.itemsize:
        raise ValueError(f"MRZ soundings of {rx['numBytesPerSounding']} bytes; this reader knows {MRZ_SOUNDING.itemsize}")
    data = reader.FID.read(count * MRZ_SOUNDING.itemsize)
    if len(data) < count * MRZ_SOUNDING.itemsize:
        raise ValueError("MRZ datagram shorter than its soundings")
    dg["sounding"] = np.frombuffer(data, MRZ_SOUNDING)
    return dg


def _read_at(f, offset: int, count: int) -> bytes:
    here = f.tell()
    f.seek(offset)
    data = f.read(count)
    f.seek(here)
    return data


def _attitude(path: Path, skipped: Counter, notes: Counter) -> dict:
    """The SKM samples' times (the sensor's own: time_sec + time_nanosec / 1e9, as pykmall computes them), roll, pitch
    and heave, in time order; of the active sensor's datagrams when the file holds more than one sensor."""
    by_sensor: dict[int, list] = {}
    active: Counter = Counter()
    for data in _datagrams(path, "SKM", skipped, raw=True):
        samples = skm_samples(data)
        if samples is None:
            skipped[f"{path.name}: damaged datagram 'SKM' (fewer samples than it says)"] += 1
            continue
        sensor, status = data[HEADER.size + 2], data[HEADER.size + 3]
        by_sensor.setdefault(sensor, []).append(samples)
        active[sensor] += bool(status & _SKM_ACTIVE)
    if not by_sensor:
        return {k: np.empty(0) for k in ("t", "roll", "pitch", "heave")}
    chosen = max(by_sensor, key=lambda s: (active[s], -s))  # the one marked active; else the lowest-numbered
    if len(by_sensor) > 1:
        others = ", ".join(str(s) for s in sorted(by_sensor) if s != chosen)
        how = "marked active" if active[chosen] else "none marked active: the lowest-numbered"
        notes[f"{path.name}: attitude from SKM sensor {chosen} ({how}); not used: SKM sensor {others}"] += 1
    out = {k: np.concatenate([s[k] for s in by_sensor[chosen]]) for k in ("t", "roll", "pitch", "heave")}
    order = np.argsort(out["t"], kind="stable")
    return {k: v[order] for k, v in out.items()}


def skm_samples(data: bytes) -> dict | None:
    """One whole SKM datagram's samples as arrays ``t``, ``roll``, ``pitch``, ``heave`` (None if it holds fewer than it says)."""
    info_bytes, _, _, _, count, per_sample, _ = _SKM_INFO.unpack_from(data, HEADER.size)
    start = HEADER.size + info_bytes
    if per_sample < _SKM_SAMPLE_MIN or start + count * per_sample > len(data) - 4:
        return None
    layout = np.dtype({"names": list(_SKM_SAMPLE_FIELDS), "formats": [f for f, _ in _SKM_SAMPLE_FIELDS.values()],
                       "offsets": [o for _, o in _SKM_SAMPLE_FIELDS.values()], "itemsize": per_sample})
    raw = np.frombuffer(data, layout, count, start)
    return {"t": raw["time_sec"].astype(np.float64) + raw["time_nanosec"] / 1.0e9, "roll": raw["roll_deg"].astype(np.float64),
            "pitch": raw["pitch_deg"].astype(np.float64), "heave": raw["heave_m"].astype(np.float64)}


def mrz_ping(dg: dict, attitude: dict) -> Ping:
    """The ping of an MRZ datagram as :func:`read_mrz` gives it; roll, pitch and heave from ``attitude`` (the SKM
    samples' times ``t`` and their ``roll``, ``pitch``, ``heave``) at the ping's time."""
    info, rx, sounding = dg["pingInfo"], dg["rxInfo"], dg["sounding"]
    main = int(rx["numSoundingsMaxMain"])
    t = np.array([dg["header"]["dgtime"]])
    roll, pitch, heave = (interpolate_at(t, attitude["t"], attitude[k], max_gap_s=_MAX_ATTITUDE_GAP_S)[0] for k in ("roll", "pitch", "heave"))
    z = np.asarray(sounding["z_reRefPoint_m"][:main], dtype=np.float64)
    valid = (np.asarray(sounding["detectionType"][:main]) == 0) & (np.asarray(sounding["detectionMethod"][:main]) != 0)
    sound_speed = float(info["soundSpeedAtTxDepth_mPerSec"])
    return Ping(
        time_s=float(t[0]), lat_deg=float(info["latitude_deg"]), lon_deg=float(info["longitude_deg"]),
        heading_deg=float(info["headingVessel_deg"]), roll_deg=float(roll), pitch_deg=float(pitch), heave_m=float(heave),
        sound_speed_mps=sound_speed if sound_speed > 0 else math.nan,
        along_m=np.asarray(sounding["x_reRefPoint_m"][:main], dtype=np.float64),
        across_m=np.asarray(sounding["y_reRefPoint_m"][:main], dtype=np.float64),
        depth_m=z - float(info["z_waterLevelReRefPoint_m"]), valid=valid, head=int(dg["cmnPart"]["rxTransducerInd"]),
        origin_depth_m=-float(info["z_waterLevelReRefPoint_m"]),
    )
