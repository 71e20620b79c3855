"""A little-endian Kongsberg .all file re-written big-endian, field by field, with ``struct`` (shared by the tests of the big-endian reader).

No real big-endian ``.all`` is at hand: older processing units wrote them, and none is published that could be
used. This writes real pings in that byte order by the format's layouts (Kongsberg's EM Series datagram
formats): the length word, the common header and the checksum word of every datagram; the bodies of the
datagrams the reader decodes ('P', 'A', 'n', 'X', 'D') field by field; the bodies of the others byte for byte
(their fields are not read). Independent of the reader's NumPy layouts.
"""

from __future__ import annotations

import struct

HEADER = ("IBBHIIHH", 20)
# Fixed parts of the decoded bodies: (format without order, repeated part, its format).
POSITION = "iiHHHHBB"
ATTITUDE_SAMPLE = "HHhhhH"
NETWORK_SAMPLE = "HhhhHB"
XYZ88_HEAD, XYZ88_BEAM = "HHfHHfB3s", "fffHBbBbh"
DEPTH_HEAD, DEPTH_BEAM = "HHHBBBBH", "hhhhHHBBbB"


def _swap(fmt: str, data: bytes, at: int) -> tuple[bytes, int]:
    size = struct.calcsize("<" + fmt)
    return struct.pack(">" + fmt, *struct.unpack_from("<" + fmt, data, at)), at + size


def _body(kind: str, frame: bytes) -> bytes:
    """The body (after the header, before ETX) of one datagram, big-endian."""
    at, end = 20, len(frame) - 3
    out = []
    if kind == "P":
        part, at = _swap(POSITION, frame, at)
        out.append(part)
    elif kind == "A":
        n = struct.unpack_from("<H", frame, at)[0]
        part, at = _swap("H", frame, at)
        out.append(part)
        for _ in range(n):
            part, at = _swap(ATTITUDE_SAMPLE, frame, at)
            out.append(part)
    elif kind == "n":
        n = struct.unpack_from("<H", frame, at)[0]
        part, at = _swap("HBB", frame, at)
        out.append(part)
        for _ in range(n):
            nbytes = frame[at + 10]
            part, at = _swap(NETWORK_SAMPLE, frame, at)
            out += [part, frame[at:at + nbytes]]
            at += nbytes
    elif kind in "XD":
        head, beam = (XYZ88_HEAD, XYZ88_BEAM) if kind == "X" else (DEPTH_HEAD, DEPTH_BEAM)
        n = struct.unpack_from("<H" if kind == "X" else "<B", frame, at + (8 if kind == "X" else 7))[0]
        part, at = _swap(head, frame, at)
        out.append(part)
        for _ in range(n):
            part, at = _swap(beam, frame, at)
            out.append(part)
    out.append(frame[at:end])  # what follows (input bytes, descriptor, spare): bytes
    return b"".join(out)


def big_endian(data: bytes) -> bytes:
    """Every datagram of a whole little-endian .all file, in the same order, big-endian."""
    out, at = [], 0
    while at + 4 <= len(data):
        length = int.from_bytes(data[at:at + 4], "little")
        frame = data[at:at + 4 + length]
        header = struct.pack(">" + HEADER[0], *struct.unpack_from("<" + HEADER[0], frame))
        checksum = int.from_bytes(frame[-2:], "little")
        out.append(header + _body(chr(frame[5]), frame) + bytes([0x03]) + checksum.to_bytes(2, "big"))
        at += 4 + length
    return b"".join(out)
