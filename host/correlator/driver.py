"""``CorrelatorDriver``: the device's wire protocol, spoken over any transport.

Written only against :class:`~lost.host.correlator.transports.Transport` (write bytes, read bytes
with a timeout), so one driver runs the reference device in-process, the Verilator co-simulation and
the board (as Glasgow's applet drivers do). The protocol is :mod:`lost.model.protocol`.

Reliability: every request carries a sequence number and the reply must echo it; replies with another
number (stale answers to an earlier, retried request) are dropped. A request is retried with a fresh
number when no reply arrives within the transport's timeout, when the reply's CRC fails, and when the
device reports a CRC or TIMEOUT error (the request arrived damaged). Every command is idempotent, so a
retry after a lost reply is safe. Other device errors raise :class:`DeviceError` at once.
"""

from __future__ import annotations

import hashlib
import logging
import struct
import time

import numpy as np

from lost.model import BestFit, Placement
from lost.model.protocol import (
    MAX_PAYLOAD,
    MAX_REPLY,
    PROTOCOL_VERSION,
    REPLY,
    Command,
    DeviceInfo,
    ErrorCode,
    FrameDecoder,
    Result,
    encode_frame,
    patch_payload,
)
from lost.model.widths import correlator_widths

from .result import Area, Outcome

__all__ = ["CorrelatorDriver", "DeviceError", "DeviceTimeout"]

log = logging.getLogger(__name__)

#: The depth word the host sends (int16).
DEPTH_BITS = 16

#: Device errors that mean the request arrived damaged: resend it.
RETRIED_ERRORS = (ErrorCode.CRC, ErrorCode.TIMEOUT)


#: The wait for one reply ends after this many transport timeouts in all, however many bytes trickle in.
_REPLY_BUDGET_TIMEOUTS = 8
#: ... or once this many of the largest frames' worth of bytes have come without the reply.
_REPLY_BUDGET_FRAMES = 4
#: The encoded size of the largest reply frame (its payload stuffed, header, CRC and delimiters).
_LARGEST_FRAME = len(encode_frame(0, Command.READ_SURFACE, bytes(MAX_REPLY)))


#: Unchanged words between two changed ones that are sent anyway rather than opening a new frame (its 11 bytes).
_MERGE_GAP = 6


def _changed_runs(new: np.ndarray, old: np.ndarray | None) -> list[tuple[int, int]]:
    """``[(first, end), ...]`` index runs of ``new`` that differ from ``old`` (all of it without ``old``)."""
    if old is None:
        return [(0, new.size)]
    changed = np.flatnonzero(new != old)
    if changed.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(changed) > _MERGE_GAP)
    firsts = np.concatenate(([changed[0]], changed[breaks + 1]))
    lasts = np.concatenate((changed[breaks], [changed[-1]]))
    return [(int(a), int(b) + 1) for a, b in zip(firsts, lasts)]


def _check_device_sizes(info: DeviceInfo) -> None:
    """Refuse a device whose reported sizes cannot serve this driver's requests (see ``identify``)."""
    shapes = {"tile": info.tile_shape, "search area": info.area_shape, "patch": info.patch_shape}
    for name, (rows, cols) in shapes.items():
        if rows < 1 or cols < 1:
            raise DeviceError(f"the device reports a {rows} x {cols} {name}: it has no node to correlate with")
    (th, tw), (ah, aw), (ph, pw) = info.tile_shape, info.area_shape, info.patch_shape
    if not (ph <= ah <= th and pw <= aw <= tw):
        raise DeviceError(f"the device reports a {ph} x {pw} patch, a {ah} x {aw} search area and a {th} x {tw} tile; "
                          "each must fit within the next")
    if info.depth_bits != DEPTH_BITS:
        raise DeviceError(f"the device takes {info.depth_bits}-bit depth words; this driver sends {DEPTH_BITS}-bit words")
    needed = correlator_widths(ph, pw, DEPTH_BITS).accumulator.bits
    if info.value_bits < needed:
        raise DeviceError(f"the device's sums are {info.value_bits} bits wide but a {ph} x {pw} patch of {DEPTH_BITS}-bit words "
                          f"needs {needed}: its surface would wrap")


class DeviceError(RuntimeError):
    """The device refused a request; ``code`` is its :class:`~lost.model.protocol.ErrorCode`."""

    def __init__(self, message: str, code: int | None = None):
        super().__init__(message)
        self.code = code


class DeviceTimeout(DeviceError):
    """No valid reply after every retry."""


class CorrelatorDriver:
    """The host side of the correlator device.

    Parameters
    ----------
    transport : Transport
        Byte pipe to the device (serial port, co-simulation, in-process reference device).
    retries : int
        Resends of a request after a timeout or a damaged frame, before :class:`DeviceTimeout`.

    Attributes
    ----------
    stats : dict
        Counters: ``requests``, ``retries``, ``stale_replies``, ``noise_replies`` (waits ended by bytes that formed
        no reply), ``tile_loads``, ``bytes_out``, ``bytes_in``.
    """

    def __init__(self, transport, *, retries: int = 3):
        if isinstance(retries, bool) or not isinstance(retries, int) or retries < 0:
            raise ValueError(f"retries must be a non-negative integer, got {retries!r}")
        self._transport = transport
        self._retries = retries
        self._seq = 0
        self._decoder = FrameDecoder(MAX_REPLY)
        self._info: DeviceInfo | None = None
        self._tile: np.ndarray | None = None  # what the device's tile holds, as far as the host knows
        self._tile_origin: tuple[int, int] | None = None  # its place in the map being searched
        self._tile_map: object | None = None  # that map's fingerprint or key
        self._patch_key: bytes | None = None
        self.stats = dict.fromkeys(("requests", "retries", "stale_replies", "noise_replies", "tile_loads", "bytes_out", "bytes_in"), 0)

    # ---- the request/reply exchange -------------------------------------------------------------

    def _next_seq(self) -> int:
        self._seq = (self._seq + 1) & 0xFF
        return self._seq

    def _await_reply(self, seq: int):
        """The first frame echoing ``seq``, a ``"damaged"`` marker, or None when no reply can be expected any more.

        A reply still arriving is not late: each read that brings bytes pushes the quiet deadline back
        by the transport's timeout. But bytes alone never keep the wait open: a port on which another
        instrument talks, line noise or a slow drip never forms the reply, so the wait ends (None) once
        ``_REPLY_BUDGET_FRAMES`` of the largest frames have arrived without it, or after
        ``_REPLY_BUDGET_TIMEOUTS`` timeouts in all (counted ``noise_replies``).
        """
        start = time.monotonic()
        quiet_deadline = start + self._transport.timeout_s
        hard_deadline = start + _REPLY_BUDGET_TIMEOUTS * self._transport.timeout_s
        received = 0
        while True:
            now = time.monotonic()
            remaining = min(quiet_deadline, hard_deadline) - now
            if remaining <= 0:
                if now >= hard_deadline and received:
                    self.stats["noise_replies"] += 1
                return None
            data = self._transport.read(65536, remaining)
            if data:  # a reply still arriving is not late
                quiet_deadline = time.monotonic() + self._transport.timeout_s
            received += len(data)
            self.stats["bytes_in"] += len(data)
            frames = self._decoder.feed(data)
            if self._decoder.errors:
                self._decoder.errors.clear()
                return "damaged"
            for frame in frames:
                if frame.seq == seq:
                    return frame
                self.stats["stale_replies"] += 1
            if received > _REPLY_BUDGET_FRAMES * _LARGEST_FRAME:
                self.stats["noise_replies"] += 1
                return None

    def transact(self, command: Command, payload: bytes = b"") -> bytes:
        """Send one request and return its reply's payload, retrying as the module says.

        Raises
        ------
        DeviceError
            The device refused the request (its error code is named).
        DeviceTimeout
            No valid reply after ``retries`` resends.
        """
        self.stats["requests"] += 1
        problem = "no reply"
        for attempt in range(self._retries + 1):
            if attempt:
                self.stats["retries"] += 1
                log.info("correlator device: %s to %s; resending (attempt %d)", problem, command.name, attempt + 1)
            seq = self._next_seq()
            frame = encode_frame(seq, command, payload)
            self._transport.write(frame)
            self.stats["bytes_out"] += len(frame)
            reply = self._await_reply(seq)
            if reply is None:
                problem = "no reply"
                self._decoder.reset()
                continue
            if reply == "damaged":
                problem = "a damaged reply"
                continue
            if reply.is_error:
                code, _ = reply.error
                if code in RETRIED_ERRORS:
                    problem = f"device error {getattr(code, 'name', code)}"
                    continue
                name = getattr(code, "name", str(code))
                raise DeviceError(f"the correlator device refused {command.name}: error {name} ({int(code)})", int(code))
            if reply.command != command | REPLY:
                raise DeviceError(f"the correlator device answered {command.name} with command 0x{reply.command:02x}")
            return reply.payload
        raise DeviceTimeout(f"the correlator device gave no valid reply to {command.name} after {self._retries + 1} attempts ({problem})")

    # ---- commands ------------------------------------------------------------------------------

    def identify(self) -> DeviceInfo:
        """What the device is; checked against the protocol version this driver speaks and against what it will be sent.

        Raises
        ------
        DeviceError
            Another protocol version; a tile, search area or patch of no node, or nested the wrong way
            (patch within area within tile); depth words other than the 16 bits the host sends; sums
            narrower than a full patch of such words needs (the device would wrap V and return a wrong
            surface).
        """
        info = DeviceInfo.decode(self.transact(Command.IDENTIFY))
        if info.version != PROTOCOL_VERSION:
            raise DeviceError(f"the device speaks protocol version {info.version}; this driver speaks {PROTOCOL_VERSION}")
        _check_device_sizes(info)
        self._info = info
        return info

    @property
    def info(self) -> DeviceInfo:
        return self._info if self._info is not None else self.identify()

    def load_tile(self, words: np.ndarray, origin: tuple[int, int] = (0, 0)) -> None:
        """Make the tile hold ``words`` (the device's tile shape) and record its origin in the map.

        Only the words that differ from what the tile is known to hold are sent (runs of them, gaps
        shorter than a frame's overhead merged), so a tile reload costs what changed.
        """
        words = np.asarray(words)
        if words.shape != self.info.tile_shape:
            raise ValueError(f"a tile is {self.info.tile_shape}, got {words.shape}")
        new = words.astype("<i2").ravel()
        old, self._tile = self._tile, None  # unknown until every chunk is acknowledged
        chunk = (MAX_PAYLOAD - 4) // 2
        for first, end in _changed_runs(new, None if old is None else old.ravel()):
            for start in range(first, end, chunk):
                self.transact(Command.LOAD_TILE, struct.pack("<I", start) + new[start : min(start + chunk, end)].tobytes())
        self.origin(origin)
        self._tile = words.astype(np.int16, copy=True)
        self.stats["tile_loads"] += 1

    def origin(self, origin: tuple[int, int] | None = None) -> tuple[int, int]:
        """Set (or, with None, read) the tile's origin, the map node of its node (0, 0)."""
        payload = b"" if origin is None else struct.pack("<ii", *(int(v) for v in origin))
        return struct.unpack("<ii", self.transact(Command.ORIGIN, payload))

    def load_patch(self, patch: np.ndarray, mask: np.ndarray, mean_compensation: bool) -> None:
        """Load a patch of exactly the device's patch shape."""
        payload = patch_payload(patch, mask, mean_compensation)
        if payload != self._patch_key:
            self._patch_key = None
            self.transact(Command.LOAD_PATCH, payload)
            self._patch_key = payload

    def start(self, row: int, col: int) -> Result:
        """Correlate the area whose top-left tile node is ``(row, col)``; the device's best fit."""
        return Result.decode(self.transact(Command.START, struct.pack("<HH", row, col)), self.info.value_bytes)

    def read_result(self) -> Result:
        return Result.decode(self.transact(Command.READ_RESULT), self.info.value_bytes)

    def read_surface(self, rows: int | None = None, cols: int | None = None) -> np.ndarray:
        """The last correlation's surface, its first ``rows`` x ``cols`` placements (default all).

        Whole rows are read as one raster range in frames of up to ``MAX_REPLY`` bytes (one round
        trip each); a narrower block row by row.
        """
        full_rows, full_cols = self.info.surface_shape
        rows, cols = rows or full_rows, cols or full_cols
        if cols == full_cols:
            return self._read_values(0, rows * cols).reshape(rows, cols)
        return np.stack([self._read_values(r * full_cols, cols) for r in range(rows)])

    def _read_values(self, first: int, count: int) -> np.ndarray:
        nbytes = self.info.value_bytes
        per_frame = MAX_REPLY // nbytes
        out = np.empty(count, dtype=np.int64)
        for at in range(0, count, per_frame):
            n = min(per_frame, count - at)
            payload = self.transact(Command.READ_SURFACE, struct.pack("<HH", first + at, n))
            if len(payload) != n * nbytes:
                raise DeviceError(f"READ_SURFACE returned {len(payload)} bytes for {n} values")
            values = np.frombuffer(payload, np.uint8).reshape(n, nbytes).astype(np.int64)
            out[at : at + n] = (values << (8 * np.arange(nbytes))).sum(axis=1)
        return out

    def reset(self) -> None:
        """Reset the core and forget the patch and result (the tile is kept)."""
        self.transact(Command.RESET)
        self._patch_key = None

    def close(self) -> None:
        self._transport.close()

    # ---- one search ------------------------------------------------------------------------------

    def _ensure_tile(self, terrain: np.ndarray, top: int, left: int, rows: int, cols: int) -> tuple[int, int]:
        """Make the map window ``[top, top+rows) x [left, left+cols)`` resident; return its tile coordinates."""
        TH, TW = self.info.tile_shape
        if self._tile is not None and self._tile_origin is not None:
            o0, o1 = self._tile_origin
            if o0 <= top and top + rows <= o0 + TH and o1 <= left and left + cols <= o1 + TW:
                return top - o0, left - o1
        o0, o1 = top, left
        tile = np.zeros((TH, TW), dtype=np.int16)
        part = terrain[o0 : o0 + TH, o1 : o1 + TW]
        tile[: part.shape[0], : part.shape[1]] = part
        if self._tile is None or not np.array_equal(tile, self._tile):
            self.load_tile(tile, (o0, o1))
        self._tile_origin = (o0, o1)
        return 0, 0

    def correlate(self, terrain: np.ndarray, patch: np.ndarray, mask: np.ndarray, mean_compensation: bool, *,
                  area: Area, exclusion_radius: int = 1, map_key: object | None = None) -> Outcome:
        """V over the in-map ``area`` of validated inputs, in pieces of the device's search area.

        ``map_key`` names the map for a caller that holds it unchanged between calls (a resident
        correlator): the tile is known to be still on the device without reading the map. Without it the
        map is fingerprinted at each call.

        A patch smaller than the device's is padded with invalid nodes (V is unchanged); a search
        larger than the device's area is done in pieces, the tile reloaded only when a piece leaves
        it. The device's best fit is returned when one piece covered exactly the search.
        """
        info = self.info
        (h, w), (dh, dw) = patch.shape, info.patch_shape
        if h > dh or w > dw:
            raise ValueError(f"the device correlates patches up to {dh} x {dw}, got {h} x {w}")
        fingerprint = map_key if map_key is not None else hashlib.blake2b(np.ascontiguousarray(terrain).data, digest_size=16).digest()
        if self._tile_map != fingerprint:
            self._tile_origin, self._tile_map = None, fingerprint  # another map: a tile's place in it means nothing
        padded_patch = np.zeros((dh, dw), dtype=np.int16)
        padded_mask = np.zeros((dh, dw), dtype=bool)
        padded_patch[:h, :w], padded_mask[:h, :w] = patch, mask
        self.load_patch(padded_patch, padded_mask, mean_compensation)
        i0, j0, rows, cols = area
        (AH, AW), (sr, sc) = info.area_shape, info.surface_shape
        # Map words past the map's edges (only padded patch nodes reach them) are zeros.
        H, W = terrain.shape
        need = (max(H, i0 + rows + dh - 1, i0 + AH), max(W, j0 + cols + dw - 1, j0 + AW))
        if need != (H, W):
            grown = np.zeros(need, dtype=np.int16)
            grown[:H, :W] = terrain
            terrain = grown
        surface = np.empty((rows, cols), dtype=np.int64)
        fit, cycles = None, 0
        for pi in range(i0, i0 + rows, sr):
            for pj in range(j0, j0 + cols, sc):
                top, left = self._ensure_tile(terrain, pi, pj, AH, AW)
                result = self.start(top, left)
                cycles += result.cycles
                n_rows, n_cols = min(sr, i0 + rows - pi), min(sc, j0 + cols - pj)
                surface[pi - i0 : pi - i0 + n_rows, pj - j0 : pj - j0 + n_cols] = self.read_surface(n_rows, n_cols)
                exact = (rows, cols) == (sr, sc) and (h, w) == (dh, dw) and exclusion_radius == info.exclusion_radius
                if exact:
                    ru = result.runner_up
                    fit = BestFit(result.i, result.j, result.value, None if ru is None else Placement(*ru), exclusion_radius)
        return Outcome(surface, fit, cycles)
