"""Joining a ``.kmall`` MRZ split into partitions (``numOfDgms``/``dgmNum``), in a file or off the network.

A K-Controller splits an MRZ bigger than a UDP datagram into parts, each a datagram of its own: the original
header (its length the part's own), the partition (``numOfDgms`` parts, this one ``dgmNum`` from 1), a slice of
the body that follows the partition, and the closing length. SIS can record them so. One rule joins them
wherever they come from (:class:`MrzJoiner`):

- an MRZ of one part is whole as it is;
- the parts of one ping are known by the header's system id, time (seconds and nanoseconds) and part count (the
  parts after the first carry no common part); they are joined in ``dgmNum`` order whatever order they come in;
- a part number outside 1..``numOfDgms`` is skipped; a part number seen twice for one key means two pings of
  one time (two heads): both are dropped, as their later parts cannot be told apart;
- a ping whose parts are not all in while :data:`PENDING_PINGS` later split pings begin, or at
  :meth:`MrzJoiner.finish`, is dropped.

Each outcome is counted in the joiner's ``counts`` under the reasons of :data:`REASONS`.
"""

from __future__ import annotations

import struct
from collections import Counter, OrderedDict

__all__ = ["MrzJoiner", "join_mrz_parts", "PENDING_PINGS", "REASONS", "DROPPED"]

#: Split pings held at once waiting for their parts; the oldest beyond this is dropped.
PENDING_PINGS = 4
HEADER = struct.Struct("<I4sBBHII")  # numBytesDgm, dgmType, dgmVersion, systemID, echoSounderID, time_sec, time_nanosec
PARTITION = struct.Struct("<HH")  # numOfDgms, dgmNum

#: The reasons counted, by outcome.
REASONS = {
    "short": "kmall #MRZ datagram too short for its parts (skipped)",
    "bad_number": "kmall #MRZ with an impossible partition number (skipped)",
    "part": "kmall #MRZ parts",
    "same_time": "MRZ parts of two pings of one time (both dropped)",
    "lost": "MRZ with parts lost (ping dropped)",
    "joined": "MRZ joined from parts",
}
#: The reasons that are data lost (a reader reports them as skips; the others are notes).
DROPPED = frozenset(REASONS[k] for k in ("short", "bad_number", "same_time", "lost"))


class MrzJoiner:
    """MRZ datagrams (whole or parts) in, whole MRZ datagrams out, by the module's rule; ``counts`` holds reason -> count."""

    def __init__(self, counts: Counter | None = None, *, pending: int = PENDING_PINGS) -> None:
        self.counts: Counter[str] = Counter() if counts is None else counts
        self._pending = pending
        self._parts: OrderedDict[tuple, dict[int, bytes]] = OrderedDict()

    def add(self, datagram: bytes) -> bytes | None:
        """The whole MRZ this datagram completes: itself when it is of one part, the joined one when it is the last
        part of its ping; ``None`` while parts are missing or when it is skipped (counted)."""
        if len(datagram) < HEADER.size + PARTITION.size + 4 + 4:
            self.counts[REASONS["short"]] += 1
            return None
        _size, _kind, _version, system, _sounder, sec, nanosec = HEADER.unpack_from(datagram)
        count, number = PARTITION.unpack_from(datagram, HEADER.size)
        if not 1 <= number <= count:
            self.counts[REASONS["bad_number"]] += 1
            return None
        if count == 1:
            return datagram
        self.counts[REASONS["part"]] += 1
        key = (system, sec, nanosec, count)
        parts = self._parts.setdefault(key, {})
        if number in parts:
            del self._parts[key]
            self.counts[REASONS["same_time"]] += 1
            return None
        parts[number] = datagram
        if len(parts) < count:
            while len(self._parts) > self._pending:
                self._parts.popitem(last=False)
                self.counts[REASONS["lost"]] += 1
            return None
        del self._parts[key]
        self.counts[REASONS["joined"]] += 1
        return join_mrz_parts([parts[k] for k in range(1, count + 1)])

    def finish(self) -> int:
        """The end of the stream: pings still missing parts are dropped and counted; returns how many."""
        lost = len(self._parts)
        if lost:
            self.counts[REASONS["lost"]] += lost
        self._parts.clear()
        return lost


def join_mrz_parts(parts: list[bytes]) -> bytes:
    """One MRZ of its parts, in ``dgmNum`` order: the first part's header, partition 1 of 1, the parts' slices, the
    closing length."""
    head = HEADER.size + PARTITION.size
    body = b"".join(part[head:-4] for part in parts)
    size = head + len(body) + 4
    first = bytearray(parts[0][:head])
    first[0:4] = size.to_bytes(4, "little")
    first[HEADER.size:head] = PARTITION.pack(1, 1)
    return bytes(first) + body + size.to_bytes(4, "little")
