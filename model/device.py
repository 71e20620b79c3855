"""The correlator device's behaviour, executable: what it answers to every frame.

:class:`DeviceModel` keeps the state the gateware keeps (tile, origin, patch, mode, last result and
surface) and answers each request as :mod:`lost.hdl.device` does, byte for byte, except for the
result's cycle count (the gateware's own clocks; the model reports 0). The gateware's simulations
compare their replies with it; the host's in-process transport uses it to test the driver without a
simulator.
"""

from __future__ import annotations

import struct

import numpy as np

from .correlator import best_fit, correlate
from .protocol import (
    ERROR,
    MAX_REPLY,
    PROTOCOL_VERSION,
    REPLY,
    Command,
    DeviceInfo,
    ErrorCode,
    Frame,
    FrameDecoder,
    Result,
    encode_frame,
    parse_patch_payload,
)

__all__ = ["DeviceModel"]


class _Refused(Exception):
    def __init__(self, code: ErrorCode):
        self.code = code


class DeviceModel:
    """A device built for ``info``'s sizes, speaking :mod:`lost.model.protocol`.

    Parameters
    ----------
    info : DeviceInfo
        What the device reports to IDENTIFY; its sizes are the tile, area and patch it holds.
    """

    def __init__(self, info: DeviceInfo):
        self.info = info
        self._decoder = FrameDecoder()
        self.tile = np.zeros(info.tile_shape, dtype=np.int16)
        self.origin = (0, 0)
        self._clear()

    def _clear(self) -> None:
        self.patch = None
        self.result: Result | None = None
        self.surface: np.ndarray | None = None

    def receive(self, data: bytes) -> bytes:
        """The reply bytes to ``data`` (any number of frames, garbage, partial frames)."""
        out = bytearray()
        frames = self._decoder.feed(data)
        for code, seq, command in self._decoder.errors:
            out += encode_frame(seq, ERROR, bytes([code, command]))
        self._decoder.errors.clear()
        for frame in frames:
            out += self._answer(frame)
        return bytes(out)

    def timeout(self) -> bytes:
        """The frame timeout expired: a partial frame is dropped with a TIMEOUT error (seq and command as received, else 0)."""
        if not self._decoder.partial:
            return b""
        partial = bytes(self._decoder._buffer)
        self._decoder.reset()
        seq = partial[1] if len(partial) > 1 else 0
        command = partial[2] if len(partial) > 2 else 0
        return encode_frame(seq, ERROR, bytes([ErrorCode.TIMEOUT, command]))

    def _answer(self, frame: Frame) -> bytes:
        try:
            handler = self._HANDLERS[frame.command]
        except KeyError:
            return encode_frame(frame.seq, ERROR, bytes([ErrorCode.COMMAND, frame.command]))
        try:
            payload = handler(self, frame.payload)
        except _Refused as refused:
            return encode_frame(frame.seq, ERROR, bytes([refused.code, frame.command]))
        return encode_frame(frame.seq, frame.command | REPLY, payload)

    # ---- commands ------------------------------------------------------------------------------

    @staticmethod
    def _length(payload: bytes, *allowed: int) -> None:
        if len(payload) not in allowed:
            raise _Refused(ErrorCode.LENGTH)

    def _identify(self, payload: bytes) -> bytes:
        self._length(payload, 0)
        return self.info.encode()

    def _load_tile(self, payload: bytes) -> bytes:
        if len(payload) < 6 or len(payload) % 2:
            raise _Refused(ErrorCode.LENGTH)
        (address,) = struct.unpack_from("<I", payload)
        words = np.frombuffer(payload[4:], dtype="<i2")
        if address + len(words) > self.tile.size:
            raise _Refused(ErrorCode.RANGE)
        self.tile.reshape(-1)[address : address + len(words)] = words
        return b""

    def _origin(self, payload: bytes) -> bytes:
        self._length(payload, 0, 8)
        if payload:
            self.origin = struct.unpack("<ii", payload)
        return struct.pack("<ii", *self.origin)

    def _load_patch(self, payload: bytes) -> bytes:
        try:
            patch, mask, mean_compensation = parse_patch_payload(payload, self.info.patch_shape)
        except ValueError:
            raise _Refused(ErrorCode.LENGTH) from None
        if not mask.any():
            raise _Refused(ErrorCode.ARGUMENT)
        self.patch = (patch, mask, mean_compensation)
        self.result = self.surface = None
        return b""

    def _start(self, payload: bytes) -> bytes:
        self._length(payload, 4)
        row, col = struct.unpack("<HH", payload)
        (TH, TW), (AH, AW) = self.info.tile_shape, self.info.area_shape
        if row + AH > TH or col + AW > TW:
            raise _Refused(ErrorCode.RANGE)
        if self.patch is None:
            raise _Refused(ErrorCode.STATE)
        patch, mask, mean_compensation = self.patch
        area = self.tile[row : row + AH, col : col + AW]
        self.surface = correlate(area, patch, mask=mask, mean_compensation=mean_compensation)
        fit = best_fit(self.surface, exclusion_radius=self.info.exclusion_radius)
        ru = fit.runner_up
        self.result = Result(fit.i, fit.j, fit.value, None if ru is None else (ru.i, ru.j, ru.value), 0)
        return self.result.encode(self.info.value_bytes)

    def _read_result(self, payload: bytes) -> bytes:
        self._length(payload, 0)
        if self.result is None:
            raise _Refused(ErrorCode.STATE)
        return self.result.encode(self.info.value_bytes)

    def _read_surface(self, payload: bytes) -> bytes:
        self._length(payload, 4)
        first, count = struct.unpack("<HH", payload)
        if count * self.info.value_bytes > MAX_REPLY:
            raise _Refused(ErrorCode.LENGTH)
        rows, cols = self.info.surface_shape
        if count == 0 or first + count > rows * cols:
            raise _Refused(ErrorCode.RANGE)
        if self.surface is None:
            raise _Refused(ErrorCode.STATE)
        nbytes = self.info.value_bytes
        return b"".join(int(v).to_bytes(nbytes, "little") for v in self.surface.ravel()[first : first + count])

    def _reset(self, payload: bytes) -> bytes:
        self._length(payload, 0)
        self._clear()
        return b""

    _HANDLERS = {
        Command.IDENTIFY: _identify,
        Command.LOAD_TILE: _load_tile,
        Command.ORIGIN: _origin,
        Command.LOAD_PATCH: _load_patch,
        Command.START: _start,
        Command.READ_RESULT: _read_result,
        Command.READ_SURFACE: _read_surface,
        Command.RESET: _reset,
    }


def reference_info(
    *,
    variant: int = 1,
    tile_shape: tuple[int, int] = (32, 32),
    area_shape: tuple[int, int] = (16, 16),
    patch_shape: tuple[int, int] = (4, 4),
    exclusion_radius: int = 1,
    clock_hz: int = 0,
) -> DeviceInfo:
    """A :class:`DeviceInfo` with the value width the core derives for the patch (16-bit words)."""
    from .variants import variant_by_id
    from .widths import correlator_widths

    return DeviceInfo(
        version=PROTOCOL_VERSION, variant=variant, lanes=variant_by_id(variant).lanes, depth_bits=16, tile_shape=tuple(tile_shape),
        area_shape=tuple(area_shape), patch_shape=tuple(patch_shape), exclusion_radius=exclusion_radius,
        value_bits=correlator_widths(*patch_shape).accumulator.bits, clock_hz=clock_hz,
    )
