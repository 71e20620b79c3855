"""The correlator device: UART, framing, a map tile in block RAM, the correlator core and control.

The host speaks :mod:`lost.model.protocol` over the UART; :class:`lost.model.device.DeviceModel` is
the executable reference of every reply (``docs/device.md`` has the tables). Requests execute one at
a time; one more frame is received while a request executes (outside the clocks that read the frame
buffer), bytes beyond it are dropped. The device never waits for the host to read.

* **Tile.** ``tile_shape`` words of the host's map (LOAD_TILE), with its origin in the map (ORIGIN).
* **Search area.** START copies the ``area_shape`` window at a tile node into the core's own map
  memory (two clocks a word), starts one correlation, stores the surface (one value a clock) and the
  best beat, and replies with the result. READ_SURFACE returns stored values.
* **Core.** Any variant of :data:`lost.hdl.variants.VARIANTS`, built for the area and the patch,
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

from .interface import CorrelatorParameters
from .link import FrameReceiver, FrameSender
from .uart import AsyncSerialRX, AsyncSerialTX
from .variants import DEFAULT_VARIANT

__all__ = ["CorrelatorDevice"]


def _zext(value: Value, bits: int) -> Value:
    value = Value.cast(value)
    return Cat(value, Const(0, bits - len(value))) if len(value) < bits else value[:bits]


class CorrelatorDevice(wiring.Component):
    """The device top-level.

    Parameters
    ----------
    variant : str
        The correlator variant (:func:`lost.hdl.variants.variant`).
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
        from .variants import variant as lookup

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
        (TH, TW), (AH, AW), (h, w) = info.tile_shape, info.area_shape, info.patch_shape
        vb, nodes = info.value_bytes, h * w
        mask_bytes = -(-nodes // 8)

        receiver, sender = self._link(m)

        core_reset = Signal()
        core = self._variant.build(map_shape=(AH, AW), patch_shape=(h, w), exclusion_radius=info.exclusion_radius)
        m.submodules.core = ResetInserter({"sync": core_reset})(core)

        payload, (tile_write, tile_read), (surface_write, surface_read) = self._memories(m, receiver)

        request = Signal.like(receiver.request.payload)
        args = Signal(64)  # the first 8 payload bytes
        k = Signal(range(max(MAX_PAYLOAD, TH * TW, nodes) + 2))  # the byte, word or node of a loop
        origin = Signal(64)
        patch_loaded, result_ready, mode = Signal(), Signal(), Signal()
        result_bits = Signal(8 * (13 + 2 * vb))
        reply_bits = Signal(8 * max(len(info.encode()), 8, 13 + 2 * vb, 2))
        reply_command, reply_length = Signal(8), Signal(range(MAX_REPLY + 1))
        from_surface = Signal()  # the reply's payload is surface values, not reply_bits
        lo, mask_bit, any_valid = Signal(8), Signal(), Signal()
        address, last = Signal(range(TH * TW + 1)), Signal(range(TH * TW + 1))
        row, col = Signal(range(AH)), Signal(range(AW))
        byte_index = Signal(range(max(vb, 8)))
        cycles, counting = Signal(32), Signal()

        def refuse(code):
            m.d.sync += [reply_bits.eq(Cat(_zext(code, 8), request.command)), reply_command.eq(ERROR),
                         reply_length.eq(2), from_surface.eq(0)]
            m.next = "REPLY"

        def answer(bits, length):
            m.d.sync += [reply_bits.eq(bits), reply_command.eq(request.command | REPLY), reply_length.eq(length),
                         from_surface.eq(0)]
            m.next = "REPLY"

        with m.FSM() as fsm:
            with m.State("IDLE"):
                m.d.comb += receiver.request.ready.eq(1)
                with m.If(receiver.request.valid):
                    m.d.sync += [request.eq(receiver.request.payload), k.eq(0)]
                    m.next = "FETCH"
            with m.State("FETCH"):  # the first 8 payload bytes into args (stale beyond the length)
                m.d.comb += payload.addr.eq(k)
                m.d.sync += k.eq(k + 1)
                with m.If(k != 0):
                    m.d.sync += args.word_select((k - 1)[:3], 8).eq(payload.data)
                with m.If(k == 8):
                    m.next = "DISPATCH"
            with m.State("DISPATCH"):
                with m.If(request.error != 0):
                    refuse(request.error)
                with m.Else():
                    self._dispatch(m, request, args, refuse, answer, origin, patch_loaded, result_ready, result_bits,
                                   k, address, last, row, col, cycles, core_reset, reply_command, reply_length,
                                   from_surface, info)
            self._load_tile_states(m, payload, tile_write, k, address, last, lo, answer)
            self._load_patch_states(m, payload, core, args, k, lo, mask_bit, any_valid, mode, patch_loaded,
                                    result_ready, refuse, answer, nodes, mask_bytes)
            self._start_states(m, core, tile_read, surface_write, address, row, col, mode, cycles, counting, k,
                               result_bits, result_ready, answer, info)
            self._reply_states(m, sender, request, reply_command, reply_length, reply_bits, from_surface, surface_read,
                               k, byte_index, address, last, vb)
        # The buffer is read from FETCH to the last patch node; a next frame may arrive during the rest.
        reading = ("FETCH", "DISPATCH", "TILE_LO", "TILE_HI", "TILE_WRITE", "MASK", "MASK_CHECK", "NODE_MASK",
                   "NODE_LO", "NODE_HI", "NODE_PUT")
        m.d.comb += [receiver.hold.eq(Cat(*(fsm.ongoing(state) for state in reading)).any()),
                     self.busy.eq(~fsm.ongoing("IDLE"))]
        with m.If(counting):
            m.d.sync += cycles.eq(cycles + 1)
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

    def _reply_states(self, m, sender, request, reply_command, reply_length, reply_bits, from_surface, surface_read, k,
                      byte_index, address, last, vb):
        """The reply: its header, then ``reply_bits`` or stored surface values (``from_surface``), then idle."""
        with m.State("REPLY"):
            m.d.comb += [sender.header.valid.eq(1), sender.header.payload.seq.eq(request.seq),
                         sender.header.payload.command.eq(reply_command), sender.header.payload.length.eq(reply_length)]
            with m.If(sender.header.ready):
                m.d.sync += [k.eq(0), byte_index.eq(0)]
                m.next = "PAYLOAD"
        with m.State("PAYLOAD"):
            with m.If(from_surface):
                m.next = "SURFACE_READ"
            with m.Elif(k == reply_length):
                m.next = "DRAIN"
            with m.Else():
                m.d.comb += [sender.payload.valid.eq(1), sender.payload.payload.eq(reply_bits.word_select(k[:bits_for(len(reply_bits) // 8)], 8))]
                with m.If(sender.payload.ready):
                    m.d.sync += k.eq(k + 1)
        with m.State("SURFACE_READ"):  # surface values address .. last-1, vb bytes each
            m.d.comb += surface_read.addr.eq(address)
            m.next = "SURFACE_BYTES"
        with m.State("SURFACE_BYTES"):
            m.d.comb += [surface_read.addr.eq(address), sender.payload.valid.eq(1),
                         sender.payload.payload.eq(surface_read.data.word_select(byte_index, 8))]
            with m.If(sender.payload.ready):
                m.d.sync += byte_index.eq(byte_index + 1)
                with m.If(byte_index == vb - 1):
                    m.d.sync += [byte_index.eq(0), address.eq(address + 1)]
                    m.next = "SURFACE_NEXT"
        with m.State("SURFACE_NEXT"):
            m.next = "SURFACE_READ"
            with m.If(address == last):
                m.next = "DRAIN"
        with m.State("DRAIN"):
            with m.If(sender.idle & ~sender.header.valid):
                m.next = "IDLE"

    def _dispatch(self, m, request, args, refuse, answer, origin, patch_loaded, result_ready, result_bits, k, address,
                  last, row, col, cycles, core_reset, reply_command, reply_length, from_surface, info):
        (TH, TW), (AH, AW), (h, w) = info.tile_shape, info.area_shape, info.patch_shape
        rows, cols = info.surface_shape
        vb, nodes = info.value_bytes, h * w
        length = request.length
        with m.Switch(request.command):
            with m.Case(Command.IDENTIFY):
                with m.If(length != 0):
                    refuse(ErrorCode.LENGTH)
                with m.Else():
                    answer(Const(int.from_bytes(info.encode(), "little"), 8 * len(info.encode())), len(info.encode()))
            with m.Case(Command.ORIGIN):
                with m.If((length != 0) & (length != 8)):
                    refuse(ErrorCode.LENGTH)
                with m.Elif(length == 8):
                    m.d.sync += origin.eq(args)
                    answer(args, 8)
                with m.Else():
                    answer(origin, 8)
            with m.Case(Command.LOAD_TILE):
                count = (length - 4) >> 1
                with m.If((length < 6) | length[0]):
                    refuse(ErrorCode.LENGTH)
                with m.Elif(args[:32] + count > TH * TW):
                    refuse(ErrorCode.RANGE)
                with m.Else():
                    m.d.sync += [address.eq(args[:32]), last.eq(args[:32] + count), k.eq(4)]
                    m.next = "TILE_LO"
            with m.Case(Command.LOAD_PATCH):
                with m.If(length != 1 + -(-nodes // 8) + 2 * nodes):
                    refuse(ErrorCode.LENGTH)
                with m.Else():
                    m.d.sync += k.eq(0)
                    m.next = "MASK"
            with m.Case(Command.START):
                top, left = args[:16], args[16:32]
                with m.If(length != 4):
                    refuse(ErrorCode.LENGTH)
                with m.Elif((top + AH > TH) | (left + AW > TW)):
                    refuse(ErrorCode.RANGE)
                with m.Elif(~patch_loaded):
                    refuse(ErrorCode.STATE)
                with m.Else():
                    m.d.sync += [address.eq(top * TW + left), row.eq(0), col.eq(0), cycles.eq(0), result_ready.eq(0)]
                    m.next = "COPY_READ"
            with m.Case(Command.READ_RESULT):
                with m.If(length != 0):
                    refuse(ErrorCode.LENGTH)
                with m.Elif(~result_ready):
                    refuse(ErrorCode.STATE)
                with m.Else():
                    answer(result_bits, len(result_bits) // 8)
            with m.Case(Command.READ_SURFACE):
                first, count = args[:16], args[16:32]
                with m.If((length != 4) | (count * vb > MAX_REPLY)):
                    refuse(ErrorCode.LENGTH)
                with m.Elif((count == 0) | (first + count > rows * cols)):
                    refuse(ErrorCode.RANGE)
                with m.Elif(~result_ready):
                    refuse(ErrorCode.STATE)
                with m.Else():
                    m.d.sync += [reply_command.eq(request.command | REPLY), reply_length.eq(count * vb),
                                 from_surface.eq(1), address.eq(first), last.eq(first + count)]
                    m.next = "REPLY"
            with m.Case(Command.RESET):
                with m.If(length != 0):
                    refuse(ErrorCode.LENGTH)
                with m.Else():
                    m.d.comb += core_reset.eq(1)
                    m.d.sync += [patch_loaded.eq(0), result_ready.eq(0)]
                    answer(0, 0)
            with m.Default():
                refuse(ErrorCode.COMMAND)

    def _load_tile_states(self, m, payload, tile_write, k, address, last, lo, answer):
        """LOAD_TILE: payload bytes 4.. as little-endian words into the tile from ``address``."""
        with m.State("TILE_LO"):
            m.d.comb += payload.addr.eq(k)
            m.next = "TILE_HI"
        with m.State("TILE_HI"):
            m.d.comb += payload.addr.eq(k + 1)
            m.d.sync += lo.eq(payload.data)
            m.next = "TILE_WRITE"
        with m.State("TILE_WRITE"):
            m.d.comb += [tile_write.addr.eq(address), tile_write.data.eq(Cat(lo, payload.data)), tile_write.en.eq(1)]
            m.d.sync += [address.eq(address + 1), k.eq(k + 2)]
            m.next = "TILE_LO"
            with m.If(address + 1 == last):
                answer(0, 0)

    def _load_patch_states(self, m, payload, core, args, k, lo, mask_bit, any_valid, mode, patch_loaded, result_ready,
                           refuse, answer, nodes, mask_bytes):
        """LOAD_PATCH: the mask must have a valid node; then every node into the core's patch_in."""
        with m.State("MASK"):  # OR of the mask bytes 1 .. mask_bytes, the last one's unused bits ignored
            m.d.comb += payload.addr.eq(1 + k)
            m.d.sync += k.eq(k + 1)
            tail = (1 << (nodes - 8 * (mask_bytes - 1))) - 1
            with m.If(k == 0):
                m.d.sync += any_valid.eq(0)
            with m.Else():
                byte = Signal(8)
                m.d.comb += byte.eq(payload.data)
                with m.If(k == mask_bytes):
                    m.d.comb += byte.eq(payload.data & tail)
                with m.If(byte != 0):
                    m.d.sync += any_valid.eq(1)
            with m.If(k == mask_bytes):
                m.next = "MASK_CHECK"
        with m.State("MASK_CHECK"):
            with m.If(~any_valid):
                refuse(ErrorCode.ARGUMENT)
            with m.Else():
                m.d.sync += [k.eq(0), mode.eq(args[0]), patch_loaded.eq(0), result_ready.eq(0)]
                m.next = "NODE_MASK"
        with m.State("NODE_MASK"):
            m.d.comb += payload.addr.eq(1 + (k >> 3))
            m.next = "NODE_LO"
        with m.State("NODE_LO"):
            m.d.comb += payload.addr.eq(1 + mask_bytes + 2 * k)
            m.d.sync += mask_bit.eq(payload.data.bit_select(k[:3], 1))
            m.next = "NODE_HI"
        with m.State("NODE_HI"):
            m.d.comb += payload.addr.eq(2 + mask_bytes + 2 * k)
            m.d.sync += lo.eq(payload.data)
            m.next = "NODE_PUT"
        with m.State("NODE_PUT"):
            m.d.comb += payload.addr.eq(2 + mask_bytes + 2 * k)  # hold the high byte on the read port
            m.d.comb += [core.patch_in.valid.eq(1), core.patch_in.payload.depth.eq(Cat(lo, payload.data)),
                         core.patch_in.payload.valid.eq(mask_bit)]
            with m.If(core.patch_in.ready):
                m.d.sync += k.eq(k + 1)
                m.next = "NODE_MASK"
                with m.If(k == nodes - 1):
                    m.d.sync += patch_loaded.eq(1)
                    answer(0, 0)

    def _start_states(self, m, core, tile_read, surface_write, address, row, col, mode, cycles, counting, k, result_bits,
                      result_ready, answer, info):
        """START: the area into the core, one correlation, the surface into its memory, the result."""
        TW, (AH, AW) = info.tile_shape[1], info.area_shape
        vb = info.value_bytes
        with m.State("COPY_READ"):
            m.d.comb += [counting.eq(1), tile_read.addr.eq(address)]
            m.next = "COPY_PUT"
        with m.State("COPY_PUT"):
            m.d.comb += [counting.eq(1), tile_read.addr.eq(address), core.map_in.valid.eq(1),
                         core.map_in.payload.eq(tile_read.data)]
            with m.If(core.map_in.ready):
                m.next = "COPY_READ"
                with m.If(col == AW - 1):
                    m.d.sync += [col.eq(0), row.eq(row + 1), address.eq(address + TW - AW + 1)]
                    with m.If(row == AH - 1):
                        m.next = "START_CORE"
                with m.Else():
                    m.d.sync += [col.eq(col + 1), address.eq(address + 1)]
        with m.State("START_CORE"):
            m.d.comb += [counting.eq(1), core.start.valid.eq(1), core.start.payload.mean_compensation.eq(mode)]
            with m.If(core.start.ready):
                m.d.sync += k.eq(0)
                m.next = "SURFACE_TAKE"
        beat = Signal.like(core.surface.payload)
        lane = Signal(range(max(info.lanes, 2)))
        with m.State("SURFACE_TAKE"):  # lane 0 of each beat written as it arrives: one beat a clock with one lane
            m.d.comb += [counting.eq(1), core.surface.ready.eq(1), surface_write.addr.eq(k),
                         surface_write.data.eq(core.surface.payload.values[0]), surface_write.en.eq(core.surface.valid)]
            with m.If(core.surface.valid):
                m.d.sync += [beat.eq(core.surface.payload), lane.eq(1), k.eq(k + 1)]
                with m.If(core.surface.payload.last):
                    m.next = "BEST"
                if info.lanes > 1:  # (a one-lane beat has one value: no comparison that is always false)
                    with m.If(core.surface.payload.count > 1):
                        m.next = "SURFACE_WRITE"
        with m.State("SURFACE_WRITE"):  # the other lanes, one value a clock, in raster order
            m.d.comb += [counting.eq(1), surface_write.addr.eq(k), surface_write.en.eq(1),
                         surface_write.data.eq(beat.values[lane])]
            m.d.sync += [k.eq(k + 1), lane.eq(lane + 1)]
            with m.If(lane == beat.count - 1):
                m.next = "SURFACE_TAKE"
                with m.If(beat.last):
                    m.next = "BEST"
        with m.State("BEST"):
            m.d.comb += [counting.eq(1), core.best.ready.eq(1)]
            with m.If(core.best.valid):
                b = core.best.payload
                # Without a runner-up its fields are unspecified in the core; zeros on the wire.
                ru = b.runner_up_valid
                bits = Cat(_zext(b.i, 16), _zext(b.j, 16), _zext(b.value, 8 * vb), _zext(ru, 8),
                           _zext(Mux(ru, b.runner_up_i, 0), 16), _zext(Mux(ru, b.runner_up_j, 0), 16),
                           _zext(Mux(ru, b.runner_up_value, 0), 8 * vb), (cycles + 1)[:32])
                m.d.sync += [result_bits.eq(bits), result_ready.eq(1)]
                answer(bits, len(bits) // 8)
