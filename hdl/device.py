"""The correlator device: UART, framing, a map tile in block RAM, the correlator core and control.

The host speaks :mod:`lost.model.protocol` over the UART; :class:`lost.model.device.DeviceModel` is
the executable reference of every reply (``docs/device.md`` has the tables). Requests execute one at
a time; one more frame is received while a request executes (outside the clocks that read the frame
buffer), bytes beyond it are dropped. The device never waits for the host to read.

* **Tile.** ``tile_shape`` words of the host's map (LOAD_TILE), with its origin in the map (ORIGIN).
* **Search area.** START copies the ``area_shape`` window at a tile node into the core's own map
  memory (two clocks a word), starts one correlation, stores the surface (one value a clock) and the
  best beat, and replies with the result. READ_SURFACE returns stored values.
* **Core.** Any variant of :data:`lost.model.variants.VARIANTS`, built for the area and the patch,
  behind a reset that RESET pulses.

The reply to START and READ_RESULT carries ``cycles``: clocks from the START request's dispatch to
the best beat (area copy and correlation).
"""

from typing import Any

from amaranth.hdl import Cat, Const, Module, Mux, ResetInserter, Signal, Value
from amaranth.lib import memory, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for

from lost.model.protocol import ERROR, MAX_PAYLOAD, MAX_REPLY, PROTOCOL_VERSION, REPLY, Command, DeviceInfo, ErrorCode
from lost.model.variants import DEFAULT_VARIANT
from lost.model.variants import variant as lookup

from .interface import CorrelatorParameters
from .link import FrameReceiver, FrameSender
from .uart import AsyncSerialRX, AsyncSerialTX
from .variants import build_core

__all__ = ["CorrelatorDevice"]


def _zext(value: Value, bits: int) -> Value:
    value = Value.cast(value)
    return Cat(value, Const(0, bits - len(value))) if len(value) < bits else value[:bits]


class _Registers:
    """The registers the device's request states share, and the two ways a request ends in a reply.

    ``k`` counts the byte, word or node of a state's loop; ``args`` holds the first 8 payload bytes;
    a reply is ``reply_bits`` (or stored surface values, ``from_surface``) under ``reply_command``.
    """

    def __init__(self, m: Module, info: DeviceInfo, request_layout: Value, core_reset: Signal):
        (TH, TW), (AH, AW), (h, w) = info.tile_shape, info.area_shape, info.patch_shape
        vb, nodes = info.value_bytes, h * w
        self._m = m
        self.core_reset = core_reset
        self.request = Signal.like(request_layout, name="request")
        self.args = Signal(64, name="args")
        self.k = Signal(range(max(MAX_PAYLOAD, TH * TW, nodes) + 2), name="k")
        self.origin = Signal(64, name="origin")
        self.patch_loaded, self.result_ready, self.mode = (Signal(name=n) for n in ("patch_loaded", "result_ready", "mode"))
        self.result_bits = Signal(8 * (13 + 2 * vb), name="result_bits")
        self.reply_bits = Signal(8 * max(len(info.encode()), 8, 13 + 2 * vb, 2), name="reply_bits")
        self.reply_command = Signal(8, name="reply_command")
        self.reply_length = Signal(range(MAX_REPLY + 1), name="reply_length")
        self.from_surface = Signal(name="from_surface")
        self.lo, self.mask_bit, self.any_valid = Signal(8, name="lo"), Signal(name="mask_bit"), Signal(name="any_valid")
        self.address, self.last = Signal(range(TH * TW + 1), name="address"), Signal(range(TH * TW + 1), name="last")
        self.row, self.col = Signal(range(AH), name="row"), Signal(range(AW), name="col")
        self.byte_index = Signal(range(max(vb, 8)), name="byte_index")
        self.cycles, self.counting = Signal(32, name="cycles"), Signal(name="counting")

    def refuse(self, code) -> None:
        """An ERROR reply naming ``code`` and the refused command."""
        self._m.d.sync += [self.reply_bits.eq(Cat(_zext(code, 8), self.request.command)), self.reply_command.eq(ERROR),
                           self.reply_length.eq(2), self.from_surface.eq(0)]
        self._m.next = "REPLY"

    def answer(self, bits, length) -> None:
        """The request's reply with ``length`` bytes of ``bits``."""
        self._m.d.sync += [self.reply_bits.eq(bits), self.reply_command.eq(self.request.command | REPLY),
                           self.reply_length.eq(length), self.from_surface.eq(0)]
        self._m.next = "REPLY"


class CorrelatorDevice(wiring.Component):
    """The device top-level.

    Parameters
    ----------
    variant : str
        The correlator variant (:func:`lost.model.variants.variant`).
    tile_shape, area_shape, patch_shape : (int, int)
        The map tile in block RAM, the search area correlated by one START (inside the tile), the patch.
    exclusion_radius : int
        The core's runner-up exclusion radius.
    divisor : int
        Clocks per UART bit.
    frame_timeout : int
        Clocks without a byte after which a partial request is dropped with a TIMEOUT error.
    clock_hz : int
        The clock, reported by IDENTIFY (0: unknown, as in simulation).

    Members
    -------
    rx : ``In(1)``
        UART receive line.
    tx : ``Out(1)``
        UART transmit line.
    busy : ``Out(1)``
        A request is being executed or answered.
    """

    rx: In(1, init=1)
    tx: Out(1, init=1)
    busy: Out(1)

    def __init__(self, *, variant: str = DEFAULT_VARIANT, tile_shape=(256, 256), area_shape=(70, 70), patch_shape=(10, 10),
                 exclusion_radius: int = 5, divisor: int = 8, frame_timeout: int = 250_000, clock_hz: int = 0):
        self._variant = lookup(variant)
        self._core_parameters = CorrelatorParameters(map_shape=area_shape, patch_shape=patch_shape,
                                                     lanes=self._variant.lanes, exclusion_radius=exclusion_radius)
        tile_shape = tuple(int(v) for v in tile_shape)
        (TH, TW), (AH, AW) = tile_shape, self._core_parameters.map_shape
        if AH > TH or AW > TW or TH > 0xFFFF or TW > 0xFFFF:
            raise ValueError(f"the search area {(AH, AW)} must fit in the tile {tile_shape}, each side below 65536")
        self._tile_shape = tile_shape
        self._divisor = divisor
        self._frame_timeout = frame_timeout
        self._info = DeviceInfo(
            version=PROTOCOL_VERSION, variant=self._variant.ident, lanes=self._variant.lanes, depth_bits=16,
            tile_shape=tile_shape, area_shape=(AH, AW), patch_shape=self._core_parameters.patch_shape,
            exclusion_radius=exclusion_radius, value_bits=self._core_parameters.value_bits, clock_hz=clock_hz)
        super().__init__()

    @property
    def info(self) -> DeviceInfo:
        """What IDENTIFY reports."""
        return self._info

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        info = self._info
        receiver, sender = self._link(m)
        core_reset = Signal()
        (AH, AW), (h, w) = info.area_shape, info.patch_shape
        core = build_core(self._variant, map_shape=(AH, AW), patch_shape=(h, w), exclusion_radius=info.exclusion_radius)
        m.submodules.core = ResetInserter({"sync": core_reset})(core)
        payload, (tile_write, tile_read), (surface_write, surface_read) = self._memories(m, receiver)
        r = _Registers(m, info, receiver.request.payload, core_reset)

        with m.FSM() as fsm:
            with m.State("IDLE"):
                m.d.comb += receiver.request.ready.eq(1)
                with m.If(receiver.request.valid):
                    m.d.sync += [r.request.eq(receiver.request.payload), r.k.eq(0)]
                    m.next = "FETCH"
            with m.State("FETCH"):  # the first 8 payload bytes into args (stale beyond the length)
                m.d.comb += payload.addr.eq(r.k)
                m.d.sync += r.k.eq(r.k + 1)
                with m.If(r.k != 0):
                    m.d.sync += r.args.word_select((r.k - 1)[:3], 8).eq(payload.data)
                with m.If(r.k == 8):
                    m.next = "DISPATCH"
            with m.State("DISPATCH"):
                with m.If(r.request.error != 0):
                    r.refuse(r.request.error)
                with m.Else():
                    self._dispatch(m, r)
            self._load_tile_states(m, r, payload, tile_write)
            self._load_patch_states(m, r, payload, core)
            self._start_states(m, r, core, tile_read, surface_write)
            self._reply_states(m, r, sender, surface_read)
        # The buffer is read from FETCH to the last patch node; a next frame may arrive during the rest.
        reading = ("FETCH", "DISPATCH", "TILE_LO", "TILE_HI", "TILE_WRITE", "MASK", "MASK_CHECK", "NODE_MASK",
                   "NODE_LO", "NODE_HI", "NODE_PUT")
        m.d.comb += [receiver.hold.eq(Cat(*(fsm.ongoing(state) for state in reading)).any()),
                     self.busy.eq(~fsm.ongoing("IDLE"))]
        with m.If(r.counting):
            m.d.sync += r.cycles.eq(r.cycles + 1)
        return m

    def _link(self, m: Module) -> tuple[FrameReceiver, FrameSender]:
        """The UART and the framing on it: the frame receiver and sender."""
        m.submodules.uart_rx = uart_rx = AsyncSerialRX(divisor=self._divisor)
        m.submodules.uart_tx = uart_tx = AsyncSerialTX(divisor=self._divisor)
        m.submodules.receiver = receiver = FrameReceiver(timeout=self._frame_timeout)
        m.submodules.sender = sender = FrameSender()
        m.d.comb += [uart_rx.rx.eq(self.rx), self.tx.eq(uart_tx.tx)]
        wiring.connect(m, uart_rx.data, receiver.bytes_in)
        wiring.connect(m, sender.bytes_out, uart_tx.data)
        return receiver, sender

    def _memories(self, m: Module, receiver: FrameReceiver) -> tuple[Any, tuple[Any, Any], tuple[Any, Any]]:
        """The frame buffer (its read port), the tile and the stored surface (their write and read ports)."""
        info = self._info
        (TH, TW), (rows, cols) = info.tile_shape, info.surface_shape
        m.submodules.buffer = buffer = memory.Memory(shape=8, depth=MAX_PAYLOAD, init=[])
        wiring.connect(m, receiver.buffer, buffer.write_port())
        payload = buffer.read_port()
        m.submodules.tile = tile = memory.Memory(shape=16, depth=TH * TW, init=[])
        tile_write, tile_read = tile.write_port(), tile.read_port()
        m.submodules.surface = surface = memory.Memory(shape=8 * info.value_bytes, depth=rows * cols, init=[])
        surface_write, surface_read = surface.write_port(), surface.read_port()
        return payload, (tile_write, tile_read), (surface_write, surface_read)

    def _reply_states(self, m: Module, r: _Registers, sender: FrameSender, surface_read) -> None:
        """The reply: its header, then ``reply_bits`` or stored surface values (``from_surface``), then idle."""
        with m.State("REPLY"):
            m.d.comb += [sender.header.valid.eq(1), sender.header.payload.seq.eq(r.request.seq),
                         sender.header.payload.command.eq(r.reply_command), sender.header.payload.length.eq(r.reply_length)]
            with m.If(sender.header.ready):
                m.d.sync += [r.k.eq(0), r.byte_index.eq(0)]
                m.next = "PAYLOAD"
        with m.State("PAYLOAD"):
            with m.If(r.from_surface):
                m.next = "SURFACE_READ"
            with m.Elif(r.k == r.reply_length):
                m.next = "DRAIN"
            with m.Else():
                byte = r.reply_bits.word_select(r.k[:bits_for(len(r.reply_bits) // 8)], 8)
                m.d.comb += [sender.payload.valid.eq(1), sender.payload.payload.eq(byte)]
                with m.If(sender.payload.ready):
                    m.d.sync += r.k.eq(r.k + 1)
        with m.State("SURFACE_READ"):  # surface values address .. last-1, vb bytes each
            m.d.comb += surface_read.addr.eq(r.address)
            m.next = "SURFACE_BYTES"
        with m.State("SURFACE_BYTES"):
            m.d.comb += [surface_read.addr.eq(r.address), sender.payload.valid.eq(1),
                         sender.payload.payload.eq(surface_read.data.word_select(r.byte_index, 8))]
            with m.If(sender.payload.ready):
                m.d.sync += r.byte_index.eq(r.byte_index + 1)
                with m.If(r.byte_index == self._info.value_bytes - 1):
                    m.d.sync += [r.byte_index.eq(0), r.address.eq(r.address + 1)]
                    m.next = "SURFACE_NEXT"
        with m.State("SURFACE_NEXT"):
            m.next = "SURFACE_READ"
            with m.If(r.address == r.last):
                m.next = "DRAIN"
        with m.State("DRAIN"):
            with m.If(sender.idle & ~sender.header.valid):
                m.next = "IDLE"

    def _dispatch(self, m: Module, r: _Registers) -> None:
        """A request's checks (an ERROR for the first that fails) and its first state, or its reply at once."""
        info = self._info
        length = r.request.length
        with m.Switch(r.request.command):
            with m.Case(Command.IDENTIFY):
                with m.If(length != 0):
                    r.refuse(ErrorCode.LENGTH)
                with m.Else():
                    answer = info.encode()
                    r.answer(Const(int.from_bytes(answer, "little"), 8 * len(answer)), len(answer))
            with m.Case(Command.ORIGIN):
                with m.If((length != 0) & (length != 8)):
                    r.refuse(ErrorCode.LENGTH)
                with m.Elif(length == 8):
                    m.d.sync += r.origin.eq(r.args)
                    r.answer(r.args, 8)
                with m.Else():
                    r.answer(r.origin, 8)
            with m.Case(Command.LOAD_TILE):
                self._accept_load_tile(m, r)
            with m.Case(Command.LOAD_PATCH):
                h, w = info.patch_shape
                with m.If(length != 1 + -(-(h * w) // 8) + 2 * h * w):
                    r.refuse(ErrorCode.LENGTH)
                with m.Else():
                    m.d.sync += r.k.eq(0)
                    m.next = "MASK"
            with m.Case(Command.START):
                self._accept_start(m, r)
            with m.Case(Command.READ_RESULT):
                with m.If(length != 0):
                    r.refuse(ErrorCode.LENGTH)
                with m.Elif(~r.result_ready):
                    r.refuse(ErrorCode.STATE)
                with m.Else():
                    r.answer(r.result_bits, len(r.result_bits) // 8)
            with m.Case(Command.READ_SURFACE):
                self._accept_read_surface(m, r)
            with m.Case(Command.RESET):
                with m.If(length != 0):
                    r.refuse(ErrorCode.LENGTH)
                with m.Else():
                    m.d.comb += r.core_reset.eq(1)
                    m.d.sync += [r.patch_loaded.eq(0), r.result_ready.eq(0)]
                    r.answer(0, 0)
            with m.Default():
                r.refuse(ErrorCode.COMMAND)

    def _accept_load_tile(self, m: Module, r: _Registers) -> None:
        """LOAD_TILE (first word, words...): the words must lie in the tile."""
        TH, TW = self._info.tile_shape
        length, first = r.request.length, r.args[:32]
        count = (length - 4) >> 1
        with m.If((length < 6) | length[0]):
            r.refuse(ErrorCode.LENGTH)
        with m.Elif(first + count > TH * TW):
            r.refuse(ErrorCode.RANGE)
        with m.Else():
            m.d.sync += [r.address.eq(first), r.last.eq(first + count), r.k.eq(4)]
            m.next = "TILE_LO"

    def _accept_start(self, m: Module, r: _Registers) -> None:
        """START (top, left): the search area must lie in the tile, a patch must be loaded."""
        (TH, TW), (AH, AW) = self._info.tile_shape, self._info.area_shape
        top, left = r.args[:16], r.args[16:32]
        with m.If(r.request.length != 4):
            r.refuse(ErrorCode.LENGTH)
        with m.Elif((top + AH > TH) | (left + AW > TW)):
            r.refuse(ErrorCode.RANGE)
        with m.Elif(~r.patch_loaded):
            r.refuse(ErrorCode.STATE)
        with m.Else():
            m.d.sync += [r.address.eq(top * TW + left), r.row.eq(0), r.col.eq(0), r.cycles.eq(0), r.result_ready.eq(0)]
            m.next = "COPY_READ"

    def _accept_read_surface(self, m: Module, r: _Registers) -> None:
        """READ_SURFACE (first, count): stored values of the last result, as many as one reply holds."""
        (rows, cols), vb = self._info.surface_shape, self._info.value_bytes
        first, count = r.args[:16], r.args[16:32]
        with m.If((r.request.length != 4) | (count * vb > MAX_REPLY)):
            r.refuse(ErrorCode.LENGTH)
        with m.Elif((count == 0) | (first + count > rows * cols)):
            r.refuse(ErrorCode.RANGE)
        with m.Elif(~r.result_ready):
            r.refuse(ErrorCode.STATE)
        with m.Else():
            m.d.sync += [r.reply_command.eq(r.request.command | REPLY), r.reply_length.eq(count * vb),
                         r.from_surface.eq(1), r.address.eq(first), r.last.eq(first + count)]
            m.next = "REPLY"

    def _load_tile_states(self, m: Module, r: _Registers, payload, tile_write) -> None:
        """LOAD_TILE: payload bytes 4.. as little-endian words into the tile from ``address``."""
        with m.State("TILE_LO"):
            m.d.comb += payload.addr.eq(r.k)
            m.next = "TILE_HI"
        with m.State("TILE_HI"):
            m.d.comb += payload.addr.eq(r.k + 1)
            m.d.sync += r.lo.eq(payload.data)
            m.next = "TILE_WRITE"
        with m.State("TILE_WRITE"):
            m.d.comb += [tile_write.addr.eq(r.address), tile_write.data.eq(Cat(r.lo, payload.data)), tile_write.en.eq(1)]
            m.d.sync += [r.address.eq(r.address + 1), r.k.eq(r.k + 2)]
            m.next = "TILE_LO"
            with m.If(r.address + 1 == r.last):
                r.answer(0, 0)

    def _load_patch_states(self, m: Module, r: _Registers, payload, core) -> None:
        """LOAD_PATCH: the mask must have a valid node; then every node into the core's patch_in."""
        h, w = self._info.patch_shape
        nodes = h * w
        mask_bytes = -(-nodes // 8)
        with m.State("MASK"):  # OR of the mask bytes 1 .. mask_bytes, the last one's unused bits ignored
            m.d.comb += payload.addr.eq(1 + r.k)
            m.d.sync += r.k.eq(r.k + 1)
            tail = (1 << (nodes - 8 * (mask_bytes - 1))) - 1
            with m.If(r.k == 0):
                m.d.sync += r.any_valid.eq(0)
            with m.Else():
                byte = Signal(8)
                m.d.comb += byte.eq(payload.data)
                with m.If(r.k == mask_bytes):
                    m.d.comb += byte.eq(payload.data & tail)
                with m.If(byte != 0):
                    m.d.sync += r.any_valid.eq(1)
            with m.If(r.k == mask_bytes):
                m.next = "MASK_CHECK"
        with m.State("MASK_CHECK"):
            with m.If(~r.any_valid):
                r.refuse(ErrorCode.ARGUMENT)
            with m.Else():
                m.d.sync += [r.k.eq(0), r.mode.eq(r.args[0]), r.patch_loaded.eq(0), r.result_ready.eq(0)]
                m.next = "NODE_MASK"
        with m.State("NODE_MASK"):
            m.d.comb += payload.addr.eq(1 + (r.k >> 3))
            m.next = "NODE_LO"
        with m.State("NODE_LO"):
            m.d.comb += payload.addr.eq(1 + mask_bytes + 2 * r.k)
            m.d.sync += r.mask_bit.eq(payload.data.bit_select(r.k[:3], 1))
            m.next = "NODE_HI"
        with m.State("NODE_HI"):
            m.d.comb += payload.addr.eq(2 + mask_bytes + 2 * r.k)
            m.d.sync += r.lo.eq(payload.data)
            m.next = "NODE_PUT"
        with m.State("NODE_PUT"):
            m.d.comb += payload.addr.eq(2 + mask_bytes + 2 * r.k)  # hold the high byte on the read port
            m.d.comb += [core.patch_in.valid.eq(1), core.patch_in.payload.depth.eq(Cat(r.lo, payload.data)),
                         core.patch_in.payload.valid.eq(r.mask_bit)]
            with m.If(core.patch_in.ready):
                m.d.sync += r.k.eq(r.k + 1)
                m.next = "NODE_MASK"
                with m.If(r.k == nodes - 1):
                    m.d.sync += r.patch_loaded.eq(1)
                    r.answer(0, 0)

    def _start_states(self, m: Module, r: _Registers, core, tile_read, surface_write) -> None:
        """START: the area into the core, one correlation, the surface into its memory, the result."""
        TW, (AH, AW) = self._info.tile_shape[1], self._info.area_shape
        with m.State("COPY_READ"):
            m.d.comb += [r.counting.eq(1), tile_read.addr.eq(r.address)]
            m.next = "COPY_PUT"
        with m.State("COPY_PUT"):
            m.d.comb += [r.counting.eq(1), tile_read.addr.eq(r.address), core.map_in.valid.eq(1),
                         core.map_in.payload.eq(tile_read.data)]
            with m.If(core.map_in.ready):
                m.next = "COPY_READ"
                with m.If(r.col == AW - 1):
                    m.d.sync += [r.col.eq(0), r.row.eq(r.row + 1), r.address.eq(r.address + TW - AW + 1)]
                    with m.If(r.row == AH - 1):
                        m.next = "START_CORE"
                with m.Else():
                    m.d.sync += [r.col.eq(r.col + 1), r.address.eq(r.address + 1)]
        with m.State("START_CORE"):
            m.d.comb += [r.counting.eq(1), core.start.valid.eq(1), core.start.payload.mean_compensation.eq(r.mode)]
            with m.If(core.start.ready):
                m.d.sync += r.k.eq(0)
                m.next = "SURFACE_TAKE"
        self._surface_states(m, r, core, surface_write)

    def _surface_states(self, m: Module, r: _Registers, core, surface_write) -> None:
        """The correlation's surface, value by value into its memory, then its best beat as the result."""
        lanes, vb = self._info.lanes, self._info.value_bytes
        beat = Signal.like(core.surface.payload)
        lane = Signal(range(max(lanes, 2)))
        with m.State("SURFACE_TAKE"):  # lane 0 of each beat written as it arrives: one beat a clock with one lane
            m.d.comb += [r.counting.eq(1), core.surface.ready.eq(1), surface_write.addr.eq(r.k),
                         surface_write.data.eq(core.surface.payload.values[0]), surface_write.en.eq(core.surface.valid)]
            with m.If(core.surface.valid):
                m.d.sync += [beat.eq(core.surface.payload), lane.eq(1), r.k.eq(r.k + 1)]
                with m.If(core.surface.payload.last):
                    m.next = "BEST"
                if lanes > 1:  # (a one-lane beat has one value: no comparison that is always false)
                    with m.If(core.surface.payload.count > 1):
                        m.next = "SURFACE_WRITE"
        with m.State("SURFACE_WRITE"):  # the other lanes, one value a clock, in raster order
            m.d.comb += [r.counting.eq(1), surface_write.addr.eq(r.k), surface_write.en.eq(1),
                         surface_write.data.eq(beat.values[lane])]
            m.d.sync += [r.k.eq(r.k + 1), lane.eq(lane + 1)]
            with m.If(lane == beat.count - 1):
                m.next = "SURFACE_TAKE"
                with m.If(beat.last):
                    m.next = "BEST"
        with m.State("BEST"):
            m.d.comb += [r.counting.eq(1), core.best.ready.eq(1)]
            with m.If(core.best.valid):
                b = core.best.payload
                # Without a runner-up its fields are unspecified in the core; zeros on the wire.
                ru = b.runner_up_valid
                bits = Cat(_zext(b.i, 16), _zext(b.j, 16), _zext(b.value, 8 * vb), _zext(ru, 8),
                           _zext(Mux(ru, b.runner_up_i, 0), 16), _zext(Mux(ru, b.runner_up_j, 0), 16),
                           _zext(Mux(ru, b.runner_up_value, 0), 8 * vb), (r.cycles + 1)[:32])
                m.d.sync += [r.result_bits.eq(bits), r.result_ready.eq(1)]
                r.answer(bits, len(bits) // 8)
