"""Kongsberg ``.all`` attitude: the attitude ('A') and network attitude velocity ('n', 0x6E) datagrams, and which sensor is used.

Both carry samples at their own times (milliseconds after the datagram's time): roll, pitch (0.01 degree),
heave (cm) and heading (0.01 degree). 'A' is a motion sensor on a serial line: after its samples (12 bytes each)
one sensor system descriptor byte. 'n' is an attitude velocity sensor on the network: after the sample count
the descriptor and a spare byte, then per sample the four values, the count of the input datagram's bytes and
those bytes as received (a variable length; the layout of Kongsberg's *EM Series datagram formats* and of
MB-System's ``mbsys_simrad3``).

A system logs several sensors at once (two motion sensors and two network sensors, each at its own rate); the
sonar uses one for each quantity, and each datagram's descriptor says whether its roll, pitch and heave are the
ones in use: bits 4-5 the sensor (00, 01: motion sensor 1, 2; 10, 11: attitude velocity sensor 1, 2), bit 1
clear for roll active, bit 2 for pitch, bit 3 for heave. Each quantity is taken from the sensor whose datagrams
mark it active, and only from that one: samples of two sensors interleaved in time would make the
interpolated attitude jump between sensors that disagree by tenths of a degree. When no datagram marks a
quantity active (an older descriptor), motion sensor 1 ('A') is used, else the first sensor of the file, and
the choice is noted. Which sensor each quantity comes from is noted whenever a file holds more than one.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .all_frames import time_s

__all__ = ["AttitudeSources", "QUANTITIES"]

ATTITUDE, NETWORK_ATTITUDE = ord("A"), ord("n")
QUANTITIES = ("roll", "pitch", "heave", "heading")
_INACTIVE_BIT = {"roll": 0x02, "pitch": 0x04, "heave": 0x08}  # a set bit: not the sonar's source of that quantity
_HEADING_ACTIVE_BIT = 0x01
_SAMPLE = np.dtype([("t_ms", "<u2"), ("status", "<u2"), ("roll", "<i2"), ("pitch", "<i2"), ("heave", "<i2"), ("heading", "<u2")])
_NETWORK_SAMPLE = np.dtype([("t_ms", "<u2"), ("roll", "<i2"), ("pitch", "<i2"), ("heave", "<i2"), ("heading", "<u2"), ("input_bytes", "u1")])
_STEPS_PER_UNIT = 100.0  # 0.01 degree, 1 cm


def _sensor_name(kind: int, descriptor: int) -> str:
    number = (descriptor >> 4) & 0x3
    if kind == ATTITUDE:
        return f"'A' motion sensor {number + 1}"
    return f"'n' attitude velocity sensor {number - 1}" if number >= 2 else f"'n' network attitude sensor (descriptor {descriptor:#04x})"


@dataclass
class _Sensor:
    name: str
    kind: int
    active: Counter = field(default_factory=Counter)  # quantity -> datagrams marking it active
    samples: list = field(default_factory=list)


class AttitudeSources:
    """Collects the attitude samples of a file by sensor; :meth:`series` gives each quantity from its active sensor."""

    def __init__(self, path: Path, order: str) -> None:
        self.path = path
        self.order = order
        self._sample = _SAMPLE if order == "<" else _SAMPLE.newbyteorder(">")
        self._network_sample = _NETWORK_SAMPLE if order == "<" else _NETWORK_SAMPLE.newbyteorder(">")
        self._sensors: dict[tuple[int, int], _Sensor] = {}

    def add(self, header, data: bytes, skipped: Counter) -> None:
        """The samples of one 'A' or 'n' datagram (whole, as framed); one holding fewer samples than it says is counted."""
        start = header.dtype.itemsize
        n = int(np.frombuffer(data, f"{self.order}u2", 1, start)[0])
        end = len(data) - 3  # ETX and checksum
        if int(header["type"]) == ATTITUDE:
            if start + 2 + n * _SAMPLE.itemsize + 1 > end:
                skipped[f"{self.path.name}: attitude datagram holding fewer samples than it says"] += 1
                return
            raw = np.frombuffer(data, self._sample, n, start + 2)
            descriptor = data[start + 2 + n * _SAMPLE.itemsize]
        else:
            descriptor = data[start + 2]
            raw = self._network_entries(data, start + 4, n, end)
            if raw is None:
                skipped[f"{self.path.name}: network attitude datagram 'n' holding fewer samples than it says"] += 1
                return
        kind = int(header["type"])
        sensor = self._sensors.setdefault((kind, (descriptor >> 4) & 0x3), _Sensor(_sensor_name(kind, descriptor), kind))
        for quantity, bit in _INACTIVE_BIT.items():
            sensor.active[quantity] += not descriptor & bit
        sensor.active["heading"] += bool(descriptor & _HEADING_ACTIVE_BIT)
        t0 = time_s(header)
        sensor.samples.append(np.column_stack([t0 + raw["t_ms"] / 1000.0] + [raw[q] / _STEPS_PER_UNIT for q in QUANTITIES]))

    def _network_entries(self, data: bytes, at: int, n: int, end: int) -> np.ndarray | None:
        """The fixed part of each 'n' entry (each followed by its input datagram's bytes), or None if they overrun the datagram."""
        offsets = np.empty(n, np.int64)
        size = self._network_sample.itemsize
        for k in range(n):
            if at + size > end:
                return None
            offsets[k] = at
            at += size + data[at + size - 1]
        if at > end:
            return None
        whole = np.frombuffer(data, np.uint8)
        return whole[offsets[:, None] + np.arange(size)].copy().view(self._network_sample).reshape(n)

    def samples(self) -> dict[str, np.ndarray]:
        """Sensor name -> its samples in file order, columns time (POSIX s) and :data:`QUANTITIES` (degrees, metres)."""
        return {s.name: np.concatenate(s.samples) for s in self._sensors.values()}

    def series(self, notes: Counter) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Quantity -> (times, values) of the sensor the sonar used for it, in time order; empty arrays without a sensor."""
        name = self.path.name
        empty = (np.empty(0), np.empty(0))
        if not self._sensors:
            return dict.fromkeys(QUANTITIES, empty)
        sensors = list(self._sensors.values())
        chosen: dict[str, _Sensor] = {}
        for quantity in QUANTITIES:
            marked = [s for s in sensors if s.active[quantity]]
            if marked:
                chosen[quantity] = max(marked, key=lambda s: s.active[quantity])  # the first of equals: max keeps it
            else:
                # Kongsberg's default: motion sensor 1 ('A'), then the lowest-numbered sensor, 'A' before 'n'.
                chosen[quantity] = min(self._sensors.items(), key=lambda item: (item[0][0] != ATTITUDE, item[0][1]))[1]
                if quantity != "heading":
                    notes[f"{name}: no attitude datagram marks {quantity} active; {quantity} from {chosen[quantity].name}"] += 1
        if len(sensors) > 1:
            used = {s.name: [q for q in QUANTITIES[:3] if chosen[q] is s] for s in sensors}
            said = "; ".join(f"{', '.join(qs)} from {who}" for who, qs in used.items() if qs)
            unused = sorted(who for who, qs in used.items() if not qs)
            notes[f"{name}: {said} (the sensor the datagrams mark active)" + (f"; not used: {', '.join(unused)}" if unused else "")] += 1
        out = {}
        for quantity in QUANTITIES:
            samples = np.concatenate(chosen[quantity].samples)
            samples = samples[np.argsort(samples[:, 0], kind="stable")]
            out[quantity] = (samples[:, 0], samples[:, 1 + QUANTITIES.index(quantity)])
        return out
