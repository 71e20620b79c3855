"""The wire protocol of the correlator device, executable: frames, CRC, commands, payload codecs.

One reference, shared by the gateware's tests (:mod:`lost.hdl.link`, :mod:`lost.hdl.device`), the
reference device (:mod:`lost.model.device`) and the host driver (:mod:`lost.host.correlator.driver`).
Numpy only, like the rest of :mod:`lost.model`.

A frame, in either direction (``docs/device.md`` has the tables)::

    0xA5 | seq | command | length (u16 LE) | payload (length bytes) | CRC-16 (u16 LE)

The CRC is CRC-16/CCITT-FALSE (polynomial 0x1021, initial 0xFFFF, no reflection; ``crc16(b"123456789")
== 0x29B1``) over ``seq``, ``command``, ``length`` and the payload. A reply carries the request's
``seq`` and ``command | 0x80``; an error reply carries the command :data:`ERROR` and the payload
``[code, request command]``. Every multi-byte field is little-endian.
"""

from __future__ import annotations

import binascii
import enum
import struct
from dataclasses import dataclass

import numpy as np

from .variants import variant_by_id

__all__ = [
    "ERROR",
    "MAX_PAYLOAD",
    "MAX_REPLY",
    "PROTOCOL_VERSION",
    "REPLY",
    "SYNC",
    "Command",
    "DeviceInfo",
    "ErrorCode",
    "Frame",
    "FrameDecoder",
    "Result",
    "crc16",
    "encode_frame",
    "patch_payload",
    "parse_patch_payload",
    "value_bytes",
]

SYNC = 0xA5
PROTOCOL_VERSION = 1
#: The largest request payload; the device's frame buffer holds this many bytes.
MAX_PAYLOAD = 1024
#: The largest reply payload: a READ_SURFACE reply of up to 16 kB (4096 four-byte values), so that a
#: 70 x 70 search area's surface comes back in one round trip.
MAX_REPLY = 16384
#: Added to a request's command in its reply.
REPLY = 0x80
#: The command byte of an error reply.
ERROR = 0xFF
HEADER_BYTES = 5
CRC_BYTES = 2


class Command(enum.IntEnum):
    """Request commands; the payloads are in ``docs/device.md``."""

    IDENTIFY = 0x01
    LOAD_TILE = 0x02
    ORIGIN = 0x03
    LOAD_PATCH = 0x04
    START = 0x05
    READ_RESULT = 0x06
    READ_SURFACE = 0x07
    RESET = 0x08


class ErrorCode(enum.IntEnum):
    """The first payload byte of an error reply."""

    CRC = 1        #: the frame's CRC does not match; nothing was executed
    LENGTH = 2     #: a payload longer than MAX_PAYLOAD, or of the wrong length for its command
    COMMAND = 3    #: an unknown command
    RANGE = 4      #: an address, area or surface index outside the device's memories
    STATE = 5      #: START before a patch was loaded, READ_* before a result exists
    TIMEOUT = 6    #: the frame stopped arriving (a gap longer than the device's frame timeout)
    ARGUMENT = 7   #: a patch mask without a valid node


def crc16(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE of ``data``, continuing from ``crc``."""
    return binascii.crc_hqx(bytes(data), crc)


def value_bytes(value_bits: int) -> int:
    """Bytes of one surface value on the wire."""
    return -(-int(value_bits) // 8)


@dataclass(frozen=True)
class Frame:
    """A decoded frame."""

    seq: int
    command: int
    payload: bytes

    @property
    def is_error(self) -> bool:
        return self.command == ERROR

    @property
    def error(self) -> tuple[ErrorCode | int, int]:
        """``(code, request command)`` of an error reply."""
        code = self.payload[0] if self.payload else 0
        try:
            code = ErrorCode(code)
        except ValueError:
            pass
        return code, self.payload[1] if len(self.payload) > 1 else 0


def encode_frame(seq: int, command: int, payload: bytes = b"", *, max_payload: int = MAX_REPLY) -> bytes:
    """The bytes of one frame; a ValueError for a field out of range or a payload over ``max_payload``."""
    payload = bytes(payload)
    if not 0 <= seq <= 255 or not 0 <= command <= 255:
        raise ValueError(f"seq and command are bytes, got seq={seq}, command={command}")
    if len(payload) > max_payload:
        raise ValueError(f"a payload of {len(payload)} bytes is longer than the protocol's {max_payload}")
    body = struct.pack("<BBH", seq, command, len(payload)) + payload
    return bytes([SYNC]) + body + struct.pack("<H", crc16(body))


class FrameDecoder:
    """Frames from a byte stream, resynchronizing after garbage, as the device's decoder does.

    :meth:`feed` returns the frames completed by the bytes given; bytes outside a frame that are not
    :data:`SYNC` are counted in :attr:`skipped`. A frame with a bad CRC or a length over
    ``max_payload`` (the device's :data:`MAX_PAYLOAD` for requests, :data:`MAX_REPLY` on the host) is
    returned as an ``(ErrorCode, seq, command)`` tuple in :attr:`errors` and dropped.
    """

    def __init__(self, max_payload: int = MAX_PAYLOAD) -> None:
        self._max_payload = max_payload
        self._buffer = bytearray()
        self.skipped = 0
        self.errors: list[tuple[ErrorCode, int, int]] = []

    def reset(self) -> None:
        """Forget a partial frame (the device's frame timeout)."""
        self._buffer.clear()

    @property
    def partial(self) -> bool:
        return bool(self._buffer)

    def feed(self, data: bytes) -> list[Frame]:
        frames = []
        data = memoryview(bytes(data))
        at = 0
        while at < len(data):
            if len(self._buffer) >= HEADER_BYTES:
                # Inside a frame's payload: take what it still needs in one slice.
                (length,) = struct.unpack_from("<H", self._buffer, 3)
                take = max(0, min(HEADER_BYTES + length + CRC_BYTES - 1 - len(self._buffer), len(data) - at))
                self._buffer += data[at : at + take]
                at += take
                if at == len(data):
                    break
            byte = data[at]
            at += 1
            if not self._buffer:
                if byte == SYNC:
                    self._buffer.append(byte)
                else:
                    self.skipped += 1
                continue
            self._buffer.append(byte)
            if len(self._buffer) < HEADER_BYTES:
                continue
            seq, command, length = struct.unpack_from("<BBH", self._buffer, 1)
            if length > self._max_payload:
                self.errors.append((ErrorCode.LENGTH, seq, command))
                self._buffer.clear()
                continue
            if len(self._buffer) < HEADER_BYTES + length + CRC_BYTES:
                continue
            body = bytes(self._buffer[1 : HEADER_BYTES + length])
            (crc,) = struct.unpack_from("<H", self._buffer, HEADER_BYTES + length)
            self._buffer.clear()
            if crc != crc16(body):
                self.errors.append((ErrorCode.CRC, seq, command))
                continue
            frames.append(Frame(seq, command, body[4:]))
        return frames


@dataclass(frozen=True)
class DeviceInfo:
    """The identify reply: what the device is and the sizes it was built for."""

    version: int
    variant: int
    lanes: int
    depth_bits: int
    tile_shape: tuple[int, int]
    area_shape: tuple[int, int]
    patch_shape: tuple[int, int]
    exclusion_radius: int
    value_bits: int
    clock_hz: int

    FORMAT = "<BBBBHHHHBBBBI"

    def encode(self) -> bytes:
        return struct.pack(self.FORMAT, self.version, self.variant, self.lanes, self.depth_bits, *self.tile_shape,
                           *self.area_shape, *self.patch_shape, self.exclusion_radius, self.value_bits, self.clock_hz)

    @classmethod
    def decode(cls, payload: bytes) -> DeviceInfo:
        if len(payload) != struct.calcsize(cls.FORMAT):
            raise ValueError(f"an identify reply has {struct.calcsize(cls.FORMAT)} bytes, got {len(payload)}")
        f = struct.unpack(cls.FORMAT, payload)
        return cls(f[0], f[1], f[2], f[3], (f[4], f[5]), (f[6], f[7]), (f[8], f[9]), f[10], f[11], f[12])

    @property
    def variant_name(self) -> str:
        """The variant's name (:func:`lost.model.variants.variant_by_id`: 0 the recursive core, L the window core of L lanes)."""
        return variant_by_id(self.variant).name

    @property
    def surface_shape(self) -> tuple[int, int]:
        """Placements of one correlation of the search area."""
        return self.area_shape[0] - self.patch_shape[0] + 1, self.area_shape[1] - self.patch_shape[1] + 1

    @property
    def value_bytes(self) -> int:
        return value_bytes(self.value_bits)


@dataclass(frozen=True)
class Result:
    """The reply to START and READ_RESULT: the best fit and runner-up the device found, relative to the area."""

    i: int
    j: int
    value: int
    runner_up: tuple[int, int, int] | None
    cycles: int

    def encode(self, value_bytes: int) -> bytes:
        ri, rj, rv = self.runner_up or (0, 0, 0)
        return (struct.pack("<HH", self.i, self.j) + self.value.to_bytes(value_bytes, "little")
                + struct.pack("<BHH", self.runner_up is not None, ri, rj) + rv.to_bytes(value_bytes, "little")
                + struct.pack("<I", self.cycles))

    @classmethod
    def decode(cls, payload: bytes, value_bytes: int) -> Result:
        if len(payload) != 13 + 2 * value_bytes:
            raise ValueError(f"a result reply has {13 + 2 * value_bytes} bytes, got {len(payload)}")
        i, j = struct.unpack_from("<HH", payload)
        value = int.from_bytes(payload[4 : 4 + value_bytes], "little")
        valid, ri, rj = struct.unpack_from("<BHH", payload, 4 + value_bytes)
        at = 9 + value_bytes
        rv = int.from_bytes(payload[at : at + value_bytes], "little")
        (cycles,) = struct.unpack_from("<I", payload, at + value_bytes)
        return cls(i, j, value, (ri, rj, rv) if valid else None, cycles)


def patch_payload(patch: np.ndarray, mask: np.ndarray, mean_compensation: bool) -> bytes:
    """LOAD_PATCH's payload: mode byte, mask bits (raster order, LSB first), then the depth words."""
    bits = np.packbits(np.asarray(mask, dtype=bool).ravel(), bitorder="little").tobytes()
    words = np.asarray(patch, dtype="<i2").ravel().tobytes()
    return bytes([int(bool(mean_compensation))]) + bits + words


def parse_patch_payload(payload: bytes, patch_shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray, bool]:
    """``(patch, mask, mean_compensation)`` of a LOAD_PATCH payload; a ValueError if its length is wrong."""
    h, w = patch_shape
    nodes = h * w
    mask_bytes = -(-nodes // 8)
    if len(payload) != 1 + mask_bytes + 2 * nodes:
        raise ValueError(f"a {h} x {w} patch payload has {1 + mask_bytes + 2 * nodes} bytes, got {len(payload)}")
    mask = np.unpackbits(np.frombuffer(payload[1 : 1 + mask_bytes], np.uint8), bitorder="little")[:nodes]
    patch = np.frombuffer(payload[1 + mask_bytes :], dtype="<i2").astype(np.int16)
    return patch.reshape(h, w), mask.astype(bool).reshape(h, w), bool(payload[0] & 1)
