"""The sending side: pings as the live datagrams a ship's network carries, optional faults, and their pacing over UDP.

Per ping, all at the ping's time: the GNSS's NMEA sentences (ZDA, GGA, VTG, HDT: :func:`lost.host.live.nmea.fix_sentences`;
course and speed differenced from the ping before, none for the first), one sentence per UDP datagram with its
CR LF; then the sonar's ``.kmall`` datagrams as a K-Controller broadcasts them (#SPO with the GGA as its sensor
text, #SKM when the ping has attitude, #MRZ; :func:`lost.host.io.kmall_write.ping_datagrams`), one datagram per
UDP datagram, an MRZ larger than ``max_datagram_bytes`` split into partitions. The pings of two heads at one
time share one fix: its sentences, #SPO and #SKM are sent once, with the first. The vehicle's own datagrams of a
simulated tow (:func:`vehicle_datagrams`: its DVL and depth as a PD6 ensemble or JSON lines, its USBL fixes with their
covariance as JSON lines or as a USBL's own ``$PSONLLD`` or ``$PSIMSSB`` sentences) go before the first ping of their time.

Faults (:class:`Faults`, one seeded NumPy generator, drawn per datagram in this order): lost (not sent), duplicated
(sent twice), reordered (held back and sent after the next one, or the next ``reorder_by``). Each is counted.
"""

from __future__ import annotations

import math
import socket
import time
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from ..io.crs import offset_metres
from ..io.kmall_write import UDP_PART_BYTES, HeadIndex, ping_datagrams, split_datagram
from ..io.survey import Ping
from .nmea import fix_sentences

__all__ = ["LiveDatagram", "Faults", "live_datagrams", "vehicle_datagrams", "usbl_line", "USBL_FORMATS", "with_faults", "send_datagrams"]

@dataclass(frozen=True)
class LiveDatagram:
    """One UDP datagram to send: its time (POSIX s), what it is (``"kmall"``, ``"nmea"``, ``"pd6"``, ``"json"``, ``"usbl"``), its bytes."""

    time_s: float
    kind: str
    payload: bytes


@dataclass(frozen=True)
class Faults:
    """Probabilities per datagram of its loss, duplication and reordering, and the generator's seed."""

    loss: float = 0.0
    reorder: float = 0.0
    duplicate: float = 0.0
    seed: int = 0
    reorder_by: int = 1  # a reordered datagram goes after this many of the ones that follow it

    def __post_init__(self) -> None:
        if not (isinstance(self.reorder_by, int) and self.reorder_by >= 1):
            raise ValueError(f"reorder_by must be a whole number of datagrams >= 1, got {self.reorder_by!r}")
        for name in ("loss", "reorder", "duplicate"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and 0.0 <= value <= 1.0):
                raise ValueError(f"{name} must be a probability from 0 to 1, got {value!r}")

    @property
    def any(self) -> bool:
        return bool(self.loss or self.reorder or self.duplicate)


def _course_speed(before: Ping | None, ping: Ping) -> tuple[float, float]:
    if before is None or ping.time_s <= before.time_s:
        return math.nan, math.nan
    north, east = offset_metres(ping.lat_deg - before.lat_deg, ping.lon_deg - before.lon_deg, ping.lat_deg)
    return math.degrees(math.atan2(east, north)) % 360.0, math.hypot(east, north) / (ping.time_s - before.time_s)


def live_datagrams(pings: Iterable[Ping], *, max_datagram_bytes: int = UDP_PART_BYTES,
                   vehicle: Iterable[LiveDatagram] | None = None) -> Iterator[LiveDatagram]:
    """The live datagrams of ``pings`` (see the module), in sending order.

    ``vehicle``: the vehicle's own datagrams (DVL, depth, USBL; :func:`vehicle_datagrams`), in time order; each is
    sent before the first ping of its time or later.
    """
    heads = HeadIndex()
    before = latest = None  # the last ping of an earlier time; the last ping
    pending = iter(vehicle or ())
    waiting = next(pending, None)
    for count, ping in enumerate(pings):
        while waiting is not None and waiting.time_s <= ping.time_s:
            yield waiting
            waiting = next(pending, None)
        # A second head's ping of the same time: its MRZ only (the sensors' fix and attitude are sent once).
        same_time = latest is not None and ping.time_s == latest.time_s
        if not same_time:
            before = latest
        course, speed = _course_speed(before, ping)
        sentences = fix_sentences(ping.time_s, ping.lat_deg, ping.lon_deg, heading_deg=ping.heading_deg, course_deg=course, speed_mps=speed)
        if not same_time:
            for sentence in sentences:
                yield LiveDatagram(ping.time_s, "nmea", (sentence + "\r\n").encode("ascii"))
        datagrams = ping_datagrams(ping, rx_index=heads(ping.head), ping_count=count, speed_mps=speed, course_deg=course,
                                   position_text=sentences[1])
        for datagram in datagrams[-1:] if same_time else datagrams:
            for part in split_datagram(datagram, max_datagram_bytes):
                yield LiveDatagram(ping.time_s, "kmall", part)
        latest = ping
    while waiting is not None:
        yield waiting
        waiting = next(pending, None)


#: The layouts a simulated USBL fix is sent in: LOST's JSON line, Sonardyne's $PSONLLD, Kongsberg's $PSIMSSB (geographic).
USBL_FORMATS = ("json", "psonlld", "psimssb")


def usbl_line(fix, usbl_format: str) -> tuple[str, str]:
    """A :class:`~lost.host.live.inputs.UsblFix` as one line of ``usbl_format`` (see :data:`USBL_FORMATS`), and its datagram
    kind (``"json"``, or ``"usbl"`` for a USBL's own NMEA-style sentence).

    ``psonlld``: the covariance as its 1-sigma error ellipse (semi-axes the square roots of its eigenvalues, the major
    axis's direction clockwise from north), to the sentence's 0.01 m and 0.01 degree. ``psimssb``: in geographic radians
    (``R``), its expected accuracy the larger semi-axis (an isotropic 1 sigma that does not understate the error), to 0.01 m.
    """
    from .inputs import json_input_line
    from .usbl_nmea import psimssb_sentence, psonlld_sentence

    if usbl_format == "json":
        return json_input_line(fix), "json"
    variances, axes = np.linalg.eigh(np.array([[fix.sxx_m2, fix.sxy_m2], [fix.sxy_m2, fix.syy_m2]]))
    major, minor = (float(math.sqrt(max(v, 0.0))) for v in variances[::-1])
    if usbl_format == "psonlld":
        direction = float(np.degrees(np.arctan2(axes[0, 1], axes[1, 1])) % 180.0)  # the major axis (east, north) from north
        return psonlld_sentence(fix, major_m=major, minor_m=minor, direction_deg=direction), "usbl"
    if usbl_format == "psimssb":
        return psimssb_sentence(fix, accuracy_m=major), "usbl"
    raise ValueError(f"usbl_format must be one of {list(USBL_FORMATS)}, got {usbl_format!r}")


def vehicle_datagrams(records, crs: str, *, dvl_format: str = "pd6", epoch_s: float = 0.0, usbl: bool = True,
                      usbl_format: str = "json") -> Iterator[LiveDatagram]:
    """The vehicle's own datagrams of a simulated tow's records (:class:`~lost.host.records.NavRecords`), one per record.

    The DVL's velocity (the records' ``vel_x_mps``/``vel_y_mps``: the simulator's own DVL, its noise, bias and dropouts)
    and the depth sensor's (``vehicle_depth_m``) as a PD6 ensemble (``:TS`` and ``:BE`` lines, ``dvl_format="pd6"``)
    or as JSON lines (``"json"``), or not at all (``"none"``); with ``usbl``, the USBL's fixes (``usbl_x_m``/``usbl_y_m``
    where finite, placed by ``crs``, with their covariance ``usbl_sxx``/``usbl_syy``/``usbl_sxy``) as lines of
    ``usbl_format`` (:func:`usbl_line`), a datagram each. Times are ``epoch_s`` plus the records' ``t_s``.
    """
    from ..io.crs import transformer
    from .inputs import DepthReading, DvlVelocity, UsblFix, json_input_line, pd6_sentences

    if dvl_format not in ("pd6", "json", "none"):
        raise ValueError(f"dvl_format must be 'pd6', 'json' or 'none', got {dvl_format!r}")
    if usbl_format not in USBL_FORMATS:
        raise ValueError(f"usbl_format must be one of {list(USBL_FORMATS)}, got {usbl_format!r}")
    to_lonlat = transformer(crs, "EPSG:4326")
    usbl_x, usbl_y = records.usbl_x_m, records.usbl_y_m  # NaN without a USBL (NavRecords fills the optional series)
    for k in range(len(records)):
        t = epoch_s + float(records.t_s[k])
        east, north, depth = float(records.vel_x_mps[k]), float(records.vel_y_mps[k]), float(records.vehicle_depth_m[k])
        if dvl_format == "pd6":
            lines = pd6_sentences(t, east, north, depth)
        elif dvl_format == "none":
            lines = []
        else:
            lines = [json_input_line(DvlVelocity(t, east, north))] if math.isfinite(east) and math.isfinite(north) else []
            lines += [json_input_line(DepthReading(t, depth))] if math.isfinite(depth) else []
        if lines:
            yield LiveDatagram(t, dvl_format, ("\r\n".join(lines) + "\r\n").encode("ascii"))
        if usbl and math.isfinite(usbl_x[k]) and math.isfinite(usbl_y[k]):
            lon, lat = to_lonlat.transform(usbl_x[k], usbl_y[k])
            covariance = (float(records.usbl_sxx[k]), float(records.usbl_syy[k]), float(records.usbl_sxy[k]))
            line, kind = usbl_line(UsblFix(t, float(lat), float(lon), depth if math.isfinite(depth) else 0.0, *covariance), usbl_format)
            yield LiveDatagram(t, kind, (line + ("\n" if kind == "json" else "\r\n")).encode("ascii"))


def with_faults(datagrams: Iterable[LiveDatagram], faults: Faults, counts: Counter) -> Iterator[LiveDatagram]:
    """``datagrams`` with the faults drawn (see the module).

    ``counts`` gets ``datagrams``, ``lost``, ``duplicated``, ``reordered``, and the first two per kind (``lost kmall``, ...).
    """
    rng = np.random.default_rng(faults.seed)
    held: list[LiveDatagram] = []
    due = 0  # datagrams still to pass the held one
    for datagram in datagrams:
        counts["datagrams"] += 1
        lost, doubled, reordered = rng.random(3) < (faults.loss, faults.duplicate, faults.reorder)
        if lost:
            counts["lost"] += 1
            counts[f"lost {datagram.kind}"] += 1
            continue
        copies = [datagram, datagram] if doubled else [datagram]
        counts["duplicated"] += int(doubled)
        counts[f"duplicated {datagram.kind}"] += int(doubled)
        if reordered and not held:
            counts["reordered"] += 1
            held, due = copies, faults.reorder_by
            continue
        yield from copies
        due -= 1
        if due <= 0:
            yield from held
            held = []
    yield from held


def send_datagrams(datagrams: Iterable[LiveDatagram], address: tuple[str, int], *, speed: float = 1.0,
                   sock: socket.socket | None = None) -> Counter:
    """Send over UDP at the datagrams' own times divided by ``speed`` (``0``: as fast as possible); counts sent per kind and bytes."""
    if not (math.isfinite(speed) and speed >= 0):
        raise ValueError(f"speed must be 0 (as fast as possible) or a positive factor of real time, got {speed!r}")
    own = sock is None
    sock = sock or socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sent: Counter = Counter()
    start_wall = first = None
    try:
        for datagram in datagrams:
            if speed > 0:
                if first is None:
                    first, start_wall = datagram.time_s, time.monotonic()
                wait = (datagram.time_s - first) / speed - (time.monotonic() - start_wall)
                if wait > 0:
                    time.sleep(wait)
            sock.sendto(datagram.payload, address)
            sent[f"{datagram.kind} datagrams sent"] += 1
            sent["bytes sent"] += len(datagram.payload)
    finally:
        if own:
            sock.close()
    return sent
