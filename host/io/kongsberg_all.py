"""Kongsberg ``.all`` files: XYZ88 or older depth ('D') datagrams as pings, with position and attitude interpolated at each ping.

A reader of its own on NumPy structured dtypes (the layout of Kongsberg's *EM Series datagram formats*,
rev. W): the one Python package that reads ``.all`` (themachinethatgoesping 0.35, "in development") gives a
ping's beams through an interface without the XYZ88 detection flags, which decide what is a valid sounding,
counts a ping whose depth datagram is missing, and pulls in numba and Jupyter widgets.

Two passes over the file: the first keeps only the active positioning system's positions ('P') and the
attitude samples ('A' and the network attitude 'n', each quantity from the sensor the datagrams mark active:
:mod:`lost.host.io.all_attitude`), small arrays (one sample per fix or per attitude reading), and counts the
datagrams of each type; the second yields one :class:`~lost.host.io.survey.Ping` per XYZ88 ('X') datagram, reading
one datagram at a time, or, in a file without XYZ88 (EM 120/300/1002/2000/3000-era sonars), one per depth ('D')
datagram. The framing, the checks and the byte order (big-endian files of older processing units are read in
their order) are :mod:`lost.host.io.all_frames`. :func:`write_all_pings` writes pings back in the three datagrams
'P', 'A' and 'X' (little-endian).

The depth datagram 'D' (Kongsberg's *EM Series datagram formats*; read as MB-System's ``mbsys_simrad2`` reads
it): per ping the heading (0.01 degree), the sound speed at the transducer (0.1 m/s), the transmit
transducer's depth (cm, plus 655.36 m times the offset multiplier after the beams, a byte EM 3000-family
sonars left undefined: not used for their models), the depth and horizontal resolutions (cm); per beam
included (the valid ones, by beam number) the depth re the transducer (unsigned for EM 120 and EM 300,
signed otherwise), the across- and along-track distances, in those resolutions. A beam of depth 0 holds no
sounding (invalid). No real 'D' file was at hand to test this reader; it is tested on real XYZ88 pings
re-expressed as 'D' datagrams with the format's scaling (``tests/host/io/test_all_depth_datagram.py``).
"""

from __future__ import annotations

import datetime as dt
import functools
import math
import os
from collections import Counter
from collections.abc import Iterable, Iterator
from pathlib import Path

import numpy as np

from .all_attitude import ATTITUDE, NETWORK_ATTITUDE, AttitudeSources
from .all_frames import ALL_HEADER, ETX, STX, byte_order, datagrams, time_s
from .crs import offset_degrees, offset_metres
from .survey import Ping, interpolate_at

__all__ = ["read_all_pings", "write_all_pings", "ALL_HEADER"]

_POSITION, _XYZ88, _DEPTH = ord("P"), ord("X"), ord("D")
# Body layouts little-endian (the usual order); :func:`_layouts` gives them in a file's order.
_XYZ88_HEAD = np.dtype([("heading", "<u2"), ("sound_speed", "<u2"), ("tx_depth", "<f4"), ("beams", "<u2"), ("valid", "<u2"),
                        ("sample_rate", "<f4"), ("scanning", "u1"), ("spare", "u1", 3)])
_XYZ88_BEAM = np.dtype([("depth", "<f4"), ("across", "<f4"), ("along", "<f4"), ("window", "<u2"), ("quality", "u1"),
                        ("incidence", "i1"), ("detection", "u1"), ("cleaning", "i1"), ("reflectivity", "<i2")])
_POSITION_BODY = np.dtype([("lat", "<i4"), ("lon", "<i4"), ("quality", "<u2"), ("speed", "<u2"), ("course", "<u2"),
                           ("heading", "<u2"), ("system", "u1"), ("input_bytes", "u1")])
_DEPTH_HEAD = np.dtype([("heading", "<u2"), ("sound_speed", "<u2"), ("tx_depth_cm", "<u2"), ("max_beams", "u1"), ("beams", "u1"),
                        ("z_res_cm", "u1"), ("xy_res_cm", "u1"), ("sample_rate", "<u2")])
_DEPTH_BEAM = np.dtype([("depth", "<i2"), ("across", "<i2"), ("along", "<i2"), ("depression", "<i2"), ("azimuth", "<u2"),
                        ("range", "<u2"), ("quality", "u1"), ("window", "u1"), ("reflectivity", "i1"), ("number", "u1")])
_UNSIGNED_DEPTH_MODELS = frozenset({120, 300})  # their 'D' depths are unsigned
_EM3000_MODELS = frozenset({3000, *range(3001, 3009), 3020})  # their transducer depth offset multiplier is undefined
_ATTITUDE_SAMPLE = np.dtype([("t_ms", "<u2"), ("status", "<u2"), ("roll", "<i2"), ("pitch", "<i2"), ("heave", "<i2"), ("heading", "<u2")])  # written
_INVALID_DETECTION = 0x80  # detection info bit 7: the beam holds no valid sounding
_ACTIVE_POSITION_SYSTEM = 0x80  # position system descriptor bit 7: the system the sonar uses
# Position or attitude samples farther apart than this around a ping leave it without that value.
_MAX_NAV_GAP_S = 10.0
_MAX_ATTITUDE_GAP_S = 1.0


def read_all_pings(path: Path, skipped: Counter, notes: Counter) -> Iterator[Ping]:
    """Pings of one ``.all`` file, in file order; damaged datagrams counted in ``skipped``, dead-reckoned positions in ``notes``."""
    order = byte_order(path)
    if order == ">":
        notes[f"{path.name}: a big-endian .all file (as older processing units wrote them), read in that byte order"] += 1
    # The first pass sees every frame too: only what it alone reads (position and attitude) is counted from it.
    first_pass, kinds = Counter(), Counter()
    positions, attitude = _navigation(path, order, first_pass, notes, kinds)
    skipped.update({reason: n for reason, n in first_pass.items() if any(word in reason for word in ("'P'", "'A'", "'n'", "position", "attitude"))})
    depth_kind = _DEPTH if kinds[_DEPTH] and not kinds[_XYZ88] else _XYZ88
    if depth_kind == _XYZ88 and kinds[_DEPTH]:
        notes[f"{path.name}: depth datagrams 'D' beside the XYZ88 ones, not read (XYZ88 is the newer form of the same soundings)"] += kinds[_DEPTH]
    decode = _xyz88_ping if depth_kind == _XYZ88 else _depth_ping
    layouts = _layouts(order)
    pings = 0
    for header, body in datagrams(path, {depth_kind}, skipped, order):
        ping = decode(path, header, body, layouts, positions, attitude, skipped, notes)
        if ping is not None:
            pings += 1
            yield ping
    if pings == 0:
        skipped[f"{path.name}: no depth datagram in the file (XYZ88 'X' or depth 'D')"] += 1


@functools.cache
def _layouts(order: str) -> dict[str, np.dtype]:
    """The datagram bodies' layouts in byte order ``order``."""
    layouts = {"xyz88_head": _XYZ88_HEAD, "xyz88_beam": _XYZ88_BEAM, "position": _POSITION_BODY, "depth_head": _DEPTH_HEAD, "depth_beam": _DEPTH_BEAM}
    return layouts if order == "<" else {k: v.newbyteorder(">") for k, v in layouts.items()}


def _navigation(path: Path, order: str, skipped: Counter, notes: Counter, kinds: Counter | None = None) -> tuple[dict, dict]:
    fixes: list[tuple[float, ...]] = []
    attitude = AttitudeSources(path, order)
    position_body = _layouts(order)["position"]
    for header, data in datagrams(path, {_POSITION, ATTITUDE, NETWORK_ATTITUDE}, skipped, order, kinds):
        if header["type"] == _POSITION:
            body = np.frombuffer(data, position_body, 1, ALL_HEADER.itemsize)[0]
            fixes.append((time_s(header), body["lat"] / 2e7, body["lon"] / 1e7, int(body["system"]), _or_nan(body["speed"]) / 100.0,
                          _or_nan(body["course"]) / 100.0))
        else:
            attitude.add(header, data, skipped)
    fix = np.array(fixes, dtype=np.float64).reshape(-1, 6)
    active = (fix[:, 3].astype(int) & _ACTIVE_POSITION_SYSTEM) != 0
    if active.any():
        fix = fix[active]
    bad = ~((np.abs(fix[:, 1]) <= 90) & (np.abs(fix[:, 2]) <= 180))
    if bad.any():
        skipped[f"{path.name}: position datagram with latitude/longitude out of range"] += int(bad.sum())
        fix = fix[~bad]
    fix = fix[np.argsort(fix[:, 0], kind="stable")]
    positions = {"t": fix[:, 0], "lat": fix[:, 1], "lon": fix[:, 2], "speed": fix[:, 4], "course": fix[:, 5]}
    return positions, attitude.series(notes)


def _xyz88_ping(path: Path, header, data: bytes, layouts: dict, positions: dict, attitude: dict, skipped: Counter, notes: Counter) -> Ping | None:
    head = np.frombuffer(data, layouts["xyz88_head"], 1, ALL_HEADER.itemsize)[0]
    n = int(head["beams"])
    start = ALL_HEADER.itemsize + _XYZ88_HEAD.itemsize
    if start + n * _XYZ88_BEAM.itemsize > len(data) - 3:
        skipped[f"{path.name}: XYZ88 datagram holding fewer beams than it says"] += 1
        return None
    beams = np.frombuffer(data, layouts["xyz88_beam"], n, start)
    tx_depth = float(head["tx_depth"])
    return _placed_ping(path, header, positions, attitude, notes, heading_deg=head["heading"] / 100.0, sound_speed_raw=int(head["sound_speed"]),
                        along_m=beams["along"].astype(np.float64), across_m=beams["across"].astype(np.float64),
                        depth_m=beams["depth"].astype(np.float64) + tx_depth, valid=(beams["detection"] & _INVALID_DETECTION) == 0,
                        origin_depth_m=tx_depth)


def _depth_ping(path: Path, header, data: bytes, layouts: dict, positions: dict, attitude: dict, skipped: Counter, notes: Counter) -> Ping | None:
    """A ping of an older depth datagram ('D'): the beams it includes, scaled by its resolutions (see the module)."""
    head = np.frombuffer(data, layouts["depth_head"], 1, ALL_HEADER.itemsize)[0]
    n = int(head["beams"])
    start = ALL_HEADER.itemsize + _DEPTH_HEAD.itemsize
    if start + n * _DEPTH_BEAM.itemsize + 1 > len(data) - 3 or n > int(head["max_beams"]):
        skipped[f"{path.name}: depth datagram 'D' holding fewer beams than it says"] += 1
        return None
    beams = np.frombuffer(data, layouts["depth_beam"], n, start)
    model = int(header["model"])
    raw_depth = (beams["depth"].astype(np.int64) & 0xFFFF) if model in _UNSIGNED_DEPTH_MODELS else beams["depth"]
    multiplier = 0 if model in _EM3000_MODELS else int(np.frombuffer(data, "i1", 1, start + n * _DEPTH_BEAM.itemsize)[0])
    tx_depth = int(head["tx_depth_cm"]) / 100.0 + 655.36 * multiplier
    z_res, xy_res = int(head["z_res_cm"]) / 100.0, int(head["xy_res_cm"]) / 100.0
    return _placed_ping(path, header, positions, attitude, notes, heading_deg=head["heading"] / 100.0, sound_speed_raw=int(head["sound_speed"]),
                        along_m=beams["along"] * xy_res, across_m=beams["across"] * xy_res,
                        depth_m=raw_depth.astype(np.float64) * z_res + tx_depth, valid=raw_depth != 0, origin_depth_m=tx_depth)


def _placed_ping(path: Path, header, positions: dict, attitude: dict, notes: Counter, *, sound_speed_raw: int, **beams) -> Ping:
    """The ping at the header's time: position and attitude interpolated from the file's fixes and samples."""
    t = np.array([time_s(header)])
    lat = interpolate_at(t, positions["t"], positions["lat"], max_gap_s=_MAX_NAV_GAP_S)[0]
    lon = interpolate_at(t, positions["t"], positions["lon"], max_gap_s=_MAX_NAV_GAP_S)[0]
    if not math.isfinite(lat) and positions["t"].size:
        lat, lon = _dead_reckoned(float(t[0]), positions)
        if math.isfinite(lat):
            notes[f"{path.name}: pings before the first or after the last fix, placed by the nearest fix's speed and course"] += 1
    roll, pitch, heave = (interpolate_at(t, *attitude[k], max_gap_s=_MAX_ATTITUDE_GAP_S)[0] for k in ("roll", "pitch", "heave"))
    return Ping(time_s=float(t[0]), lat_deg=float(lat), lon_deg=float(lon), roll_deg=float(roll), pitch_deg=float(pitch), heave_m=float(heave),
                sound_speed_mps=sound_speed_raw / 10.0 if sound_speed_raw else math.nan, head=int(header["serial"]), **beams)


def _dead_reckoned(t: float, positions: dict) -> tuple[float, float]:
    """The position at ``t`` from the nearest fix, its speed over ground and course, within ``_MAX_NAV_GAP_S``."""
    k = int(np.argmin(np.abs(positions["t"] - t)))
    dt_s = t - positions["t"][k]
    if abs(dt_s) > _MAX_NAV_GAP_S:
        return math.nan, math.nan
    lat0, lon0 = positions["lat"][k], positions["lon"][k]
    speed, course = positions["speed"][k], positions["course"][k]
    if math.isfinite(speed) and math.isfinite(course):
        north, east = speed * math.cos(math.radians(course)), speed * math.sin(math.radians(course))
    else:
        # Without a logged speed and course, the velocity of the fixes at that end of the file.
        near = np.flatnonzero(np.abs(positions["t"] - positions["t"][k]) <= _MAX_NAV_GAP_S)
        j = near[np.argmax(np.abs(positions["t"][near] - positions["t"][k]))]
        span = positions["t"][j] - positions["t"][k]
        if abs(span) < 0.1:
            return math.nan, math.nan
        north, east = offset_metres(positions["lat"][j] - lat0, positions["lon"][j] - lon0, lat0)
        north, east = north / span, east / span
    dlat, dlon = offset_degrees(north * dt_s, east * dt_s, lat0)  # a few seconds of dead reckoning
    return float(lat0 + dlat), float(lon0 + dlon)


def _or_nan(value) -> float:
    return math.nan if int(value) == 0xFFFF else float(value)



# --------------------------------------------------------------------------------------------
# writing


def write_all_pings(pings: Iterable[Ping], path: str | os.PathLike, *, model: int = 710) -> Path:
    """Write pings as a Kongsberg ``.all`` file: per ping a position ('P'), an attitude ('A') and an XYZ88 ('X') datagram.

    What :func:`read_all_pings` reads back: times to the millisecond, latitude to 1/20,000,000 degree,
    longitude to 1/10,000,000, heading, roll and pitch to 0.01 degree, heave to 1 cm, sound speed to
    0.1 m/s, per beam along, across and depth as float32, the valid flag (detection info bit 7). The
    transducer depth is the ping's ``origin_depth_m`` (0 when unknown) and the XYZ88 depths are re it. A ping without
    roll, pitch or heave gets no attitude datagram (the reader interpolates those of pings within 1 s). Pings are
    written as they come (one at a time); the file is written whole to ``NAME.partial``, then renamed.
    Returns the path.
    """
    path = Path(path)
    partial = path.with_name(path.name + ".partial")
    try:
        with partial.open("wb") as out:
            for counter, ping in enumerate(pings):
                if not (math.isfinite(ping.lat_deg) and math.isfinite(ping.lon_deg) and math.isfinite(ping.heading_deg)):
                    raise ValueError(f"ping {counter} at t={ping.time_s} has no position or heading; an .all ping needs both")
                out.write(_position_datagram(ping, counter, model))
                if all(math.isfinite(v) for v in (ping.roll_deg, ping.pitch_deg, ping.heave_m)):
                    out.write(_attitude_datagram(ping, counter, model))
                out.write(_xyz88_datagram(ping, counter, model))
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)
    return path


def _framed(kind: int, ping: Ping, counter: int, model: int, body: bytes) -> bytes:
    moment = dt.datetime.fromtimestamp(ping.time_s, dt.UTC)
    midnight = moment.replace(hour=0, minute=0, second=0, microsecond=0)
    header = np.zeros(1, ALL_HEADER)
    if len(body) % 2:
        body += b"\x00"  # Kongsberg datagrams have an even length
    header["length"] = ALL_HEADER.itemsize - 4 + len(body) + 3
    header["stx"], header["type"], header["model"] = STX, kind, model
    header["date"] = moment.year * 10000 + moment.month * 100 + moment.day
    header["time_ms"] = round((ping.time_s - midnight.timestamp()) * 1000)
    header["counter"], header["serial"] = counter & 0xFFFF, ping.head & 0xFFFF
    framed = header.tobytes() + body
    checksum = int(np.frombuffer(framed, np.uint8, len(framed) - 5, 5).sum()) & 0xFFFF
    return framed + bytes([ETX]) + checksum.to_bytes(2, "little")


def _angle(value: float, scale: float, dtype: str) -> int:
    info = np.iinfo(dtype)
    return int(np.clip(round(value * scale), info.min, info.max)) if math.isfinite(value) else 0


def _position_datagram(ping: Ping, counter: int, model: int) -> bytes:
    body = np.zeros(1, _POSITION_BODY)
    body["lat"], body["lon"] = round(ping.lat_deg * 2e7), round(ping.lon_deg * 1e7)
    body["speed"] = body["course"] = 0xFFFF  # not available: the positions themselves are written, one per ping
    body["heading"] = _angle(ping.heading_deg % 360.0, 100, "<u2")
    body["system"] = _ACTIVE_POSITION_SYSTEM | 1
    return _framed(_POSITION, ping, counter, model, body.tobytes())


def _attitude_datagram(ping: Ping, counter: int, model: int) -> bytes:
    sample = np.zeros(1, _ATTITUDE_SAMPLE)
    sample["roll"], sample["pitch"] = _angle(ping.roll_deg, 100, "<i2"), _angle(ping.pitch_deg, 100, "<i2")
    sample["heave"], sample["heading"] = _angle(ping.heave_m, 100, "<i2"), _angle(ping.heading_deg % 360.0, 100, "<u2")
    return _framed(ATTITUDE, ping, counter, model, np.uint16(1).tobytes() + sample.tobytes() + b"\x00")


def _xyz88_datagram(ping: Ping, counter: int, model: int) -> bytes:
    head = np.zeros(1, _XYZ88_HEAD)
    origin = ping.origin_depth_m if math.isfinite(ping.origin_depth_m) else 0.0
    head["heading"], head["tx_depth"] = _angle(ping.heading_deg % 360.0, 100, "<u2"), origin
    head["sound_speed"] = _angle(ping.sound_speed_mps, 10, "<u2")
    head["beams"], head["valid"] = ping.beams, int(ping.valid.sum())
    beams = np.zeros(ping.beams, _XYZ88_BEAM)
    beams["depth"], beams["across"], beams["along"] = ping.depth_m - origin, ping.across_m, ping.along_m
    beams["detection"] = np.where(ping.valid, 0, _INVALID_DETECTION)
    return _framed(_XYZ88, ping, counter, model, head.tobytes() + beams.tobytes())
