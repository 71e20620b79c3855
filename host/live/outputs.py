"""What `lost serve` sends and keeps: each estimate as a JSON line and a ``$LOSTE`` sentence on UDP, and the run's log.

The JSON line is :meth:`~lost.host.live.navigator.LiveEstimate.as_dict` (missing values ``null``), compact, with
a line feed. The sentence, NMEA 0183-style (talker ``LO``, our own, so survey software never mistakes it for a GNSS's)::

    $LOEST,hhmmss.ss,RECORD,ESTIMATOR,EAST,NORTH,SXX,SYY,SXY,U*hh

time of day UTC of the record, the record number, the estimator's name, east and north in metres (the map's CRS,
3 decimals), the covariance in m**2 (east variance, north variance, their covariance, 3 decimals), ``A`` usable or
``V`` not; empty fields for missing values; ``hh`` the XOR of the characters between ``$`` and ``*``, as NMEA's.

:class:`RunLog` appends one JSON line per record (all its estimators' answers), and a line for each input or event
logged as it comes (``{"usbl": {...}}``, ``{"correlator": {...}}``), each with one ``write`` of the whole line,
unbuffered (the line is in the kernel's page cache when ``write`` returns): a line in the file is whole or absent
whatever stops the process; a power loss may lose the last lines not yet on disk (no fsync per line).
"""

from __future__ import annotations

import json
import math
import socket
import time
from collections import Counter
from collections.abc import Iterable
from pathlib import Path

from .navigator import LiveEstimate

__all__ = ["json_line", "estimate_sentence", "nmea_checksum", "UdpSender", "RunLog", "SENTENCE"]

SENTENCE = "LOEST"


def json_line(estimate: LiveEstimate) -> bytes:
    return (json.dumps(estimate.as_dict(), separators=(",", ":"), allow_nan=False) + "\n").encode("ascii")


def nmea_checksum(body: str) -> str:
    value = 0
    for character in body.encode("ascii"):
        value ^= character
    return f"{value:02X}"


def estimate_sentence(estimate: LiveEstimate) -> str:
    """The ``$LOEST`` sentence of an estimate (see the module), without its CR LF."""
    def cell(value: float) -> str:
        return f"{value:.3f}" if math.isfinite(value) else ""

    t = time.gmtime(math.floor(estimate.time_utc_s))
    seconds = t.tm_sec + (estimate.time_utc_s - math.floor(estimate.time_utc_s))
    body = ",".join([SENTENCE, f"{t.tm_hour:02d}{t.tm_min:02d}{seconds:05.2f}", str(estimate.record), estimate.estimator,
                     cell(estimate.east_m), cell(estimate.north_m), *(cell(v) for v in estimate.covariance_m2), "A" if estimate.usable else "V"])
    return f"${body}*{nmea_checksum(body)}"


class UdpSender:
    """Each estimate to every address, as a JSON datagram and a sentence datagram; a failed send is counted, never a stop."""

    def __init__(self, addresses: Iterable[tuple[str, int]]) -> None:
        self.addresses = list(addresses)
        self.counts: Counter[str] = Counter()
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def send(self, estimate: LiveEstimate) -> None:
        payloads = (json_line(estimate), (estimate_sentence(estimate) + "\r\n").encode("ascii"))
        for address in self.addresses:
            for payload in payloads:
                try:
                    self._sock.sendto(payload, address)
                    self.counts["output datagrams sent"] += 1
                except OSError as error:  # no route, refused by an ICMP reply, a full buffer
                    self.counts[f"output datagrams not sent ({type(error).__name__})"] += 1

    def close(self) -> None:
        self._sock.close()


class RunLog:
    """``log.jsonl``: one line per record, written whole and flushed as the record is served (see the module)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._file = open(path, "ab", buffering=0)  # unbuffered: one write() per line, nothing held back in Python

    def record(self, estimates: list[LiveEstimate]) -> None:
        if not estimates:
            return
        first = estimates[0]
        self.line({"record": first.record, "time_utc_s": first.time_utc_s, "t_s": first.t_s,
                   "estimates": {e.estimator: {k: v for k, v in e.as_dict().items() if k not in ("record", "time_utc_s", "t_s", "estimator")}
                                 for e in estimates}})

    def line(self, value: dict) -> None:
        """One line of the log (a record's, or an input logged as it came: ``{"usbl": {...}}``), whole, in one write."""
        self._file.write((json.dumps(value, separators=(",", ":"), allow_nan=False) + "\n").encode("ascii"))

    def close(self) -> None:
        self._file.close()
