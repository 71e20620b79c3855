"""Kongsberg ``.all`` framing: the datagrams of a file, each checked, in either byte order.

A datagram is a length word (the bytes after itself), STX (0x02), the type byte, the common header, the
body, ETX (0x03) and a 16-bit checksum of the bytes between STX and ETX. Sonars since the EM 300/3000 write
them little-endian; older processing units wrote big-endian files. The order is the file's, told by its first
datagram: the one order in which the length word lands on an ETX (:func:`byte_order`). Every multi-byte field
of the file is then read in that order (the checksum word too; the sum of bytes is the same in both).

A datagram whose frame does not hold (no STX, a length beyond any datagram, no ETX where the length says) is
damaged: the reader resynchronises on the next well-framed datagram and counts the gap; a datagram cut off by
the end of the file ends the reading, counted; a wrong checksum skips the datagram, counted.
"""

from __future__ import annotations

import datetime as dt
from collections import Counter
from collections.abc import Iterator
from pathlib import Path

import numpy as np

__all__ = ["ALL_HEADER", "byte_order", "datagrams", "header_dtype", "time_s"]

STX, ETX = 0x02, 0x03
_MAX_DATAGRAM = 1 << 26  # no .all datagram is 64 MiB; a length beyond it is a damaged length field

# The length field counts the bytes after itself; the header's fields follow it (little-endian, the usual order).
ALL_HEADER = np.dtype([("length", "<u4"), ("stx", "u1"), ("type", "u1"), ("model", "<u2"), ("date", "<u4"), ("time_ms", "<u4"),
                       ("counter", "<u2"), ("serial", "<u2")])


def header_dtype(order: str) -> np.dtype:
    """The common header in byte order ``order`` (``"<"`` or ``">"``)."""
    return ALL_HEADER if order == "<" else ALL_HEADER.newbyteorder(">")


def byte_order(path: Path) -> str:
    """``"<"`` or ``">"``: the order in which the file's first well-framed datagram's length word ends on its ETX.

    The first datagram decides; when it is damaged, the first of the file's first MiB that frames in one order
    and has a plausible date. A file in which none frames is read little-endian (and its damage counted).
    """
    size = path.stat().st_size
    with path.open("rb") as f:
        chunk = f.read(1 << 20)
        starts = [0] + [int(k) - 4 for k in np.flatnonzero(np.frombuffer(chunk, np.uint8) == STX) if k >= 4]
        for at in starts:
            if chunk[at + 4:at + 5] != bytes([STX]) or at + ALL_HEADER.itemsize > len(chunk):
                continue
            for order in ("<", ">"):
                header = np.frombuffer(chunk, header_dtype(order), 1, at)[0]
                length = int(header["length"])
                if not (ALL_HEADER.itemsize - 4 <= length <= _MAX_DATAGRAM and at + 4 + length <= size):
                    continue
                f.seek(at + 4 + length - 3)
                if f.read(1) == bytes([ETX]) and (at == 0 or 1980 < int(header["date"]) // 10000 < 2200):
                    return order
    return "<"


def time_s(header) -> float:
    """POSIX seconds of a datagram header's date (YYYYMMDD) and milliseconds since midnight."""
    date = int(header["date"])
    day = dt.datetime(date // 10000, date // 100 % 100, date % 100, tzinfo=dt.UTC)
    return day.timestamp() + int(header["time_ms"]) / 1000.0


def datagrams(path: Path, wanted: set[int], skipped: Counter, order: str, kinds: Counter | None = None) -> Iterator[tuple[np.void, bytes]]:
    """(header, whole datagram) of each wanted datagram whose frame and checksum hold; others are skipped by seeking.
    ``kinds`` counts every well-framed datagram by type."""
    header_type = header_dtype(order)
    checksum_order = "little" if order == "<" else "big"
    size = path.stat().st_size
    with path.open("rb") as f:
        at = 0
        while at + header_type.itemsize <= size:
            f.seek(at)
            header = np.frombuffer(f.read(header_type.itemsize), header_type)[0]
            length = int(header["length"])
            if header["stx"] != STX or not header_type.itemsize - 4 <= length <= _MAX_DATAGRAM:
                at = _resync(f, at + 1, size, path, skipped, header_type)
                continue
            end = at + 4 + length
            if end > size:
                skipped[f"{path.name}: datagram cut off by the end of the file ({size - at} of {length + 4} bytes)"] += 1
                return
            f.seek(end - 3)
            if f.read(1)[0] != ETX:
                at = _resync(f, at + 1, size, path, skipped, header_type)
                continue
            if kinds is not None:
                kinds[int(header["type"])] += 1
            if int(header["type"]) in wanted:
                f.seek(at)
                data = f.read(length + 4)
                checksum = int.from_bytes(data[-2:], checksum_order)
                if int(np.frombuffer(data, np.uint8, length - 4, 5).sum()) & 0xFFFF != checksum:
                    skipped[f"{path.name}: datagram '{chr(header['type'])}' with a wrong checksum"] += 1
                else:
                    yield header, data
            at = end


def _resync(f, start: int, size: int, path: Path, skipped: Counter, header_type: np.dtype) -> int:
    """The offset of the next well-framed datagram at or after ``start`` (or the end of the file); the gap is counted."""
    chunk_start = start
    while chunk_start < size:
        f.seek(chunk_start)
        chunk = f.read(1 << 20)
        for k in np.flatnonzero(np.frombuffer(chunk, np.uint8) == STX):
            at = chunk_start + int(k) - 4
            if at < start or at + header_type.itemsize > size:
                continue
            f.seek(at)
            header = np.frombuffer(f.read(header_type.itemsize), header_type)[0]
            length = int(header["length"])
            if not 16 <= length <= _MAX_DATAGRAM or at + 4 + length > size:
                continue
            f.seek(at + 4 + length - 3)
            if f.read(1)[0] == ETX and header["date"] // 10000 > 1980:
                skipped[f"{path.name}: bytes that are no datagram (damaged data, resynchronised)"] += 1
                return at
        chunk_start += max(len(chunk) - header_type.itemsize, 1)
    skipped[f"{path.name}: bytes that are no datagram (damaged data, resynchronised)"] += 1
    return size
