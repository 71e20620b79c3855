"""The window correlator's output queue, and the credits that keep its pipeline from ever stalling."""

from __future__ import annotations

from typing import Any

from amaranth.hdl import Module, Mux, Shape, ShapeLike, Signal, Value
from amaranth.lib import memory, stream, wiring
from amaranth.lib.wiring import In, Out

from lost.hdl.blocks import Replicas

__all__ = ["CreditQueue"]

#: Bits of a beat stored per copy of the read pointer (four distributed-RAM cells of 4 bits).
SLICE_BITS = 16


class CreditQueue(wiring.Component):
    """A queue of ``depth`` beats with one credit per place: a step is issued only against a credit.

    The pipeline before the queue cannot stall (its term stages run on every clock), so every beat it
    will write must find room: a step takes a credit when it is issued (``issue``), and gives it back
    when its beat leaves the queue, or when it leaves the pipeline without a beat (``passed``). Then
    ``surface.ready`` stalls nothing but the issue of further steps.

    Latency: a beat written on one edge can transfer on the next (the queue adds no cycle). A credit
    taken or returned on an edge counts from that edge.

    Parameters
    ----------
    shape : ShapeLike
        Of a beat.
    depth : int
        Beats held, and credits.

    Members
    -------
    write : ``In(stream.Signature(shape, always_ready=True))``
        A beat into the queue (there is room by construction: the credits).
    write_next : ``In(1)``
        The value ``write.valid`` takes on the next edge: the storage's slices write at copies of their own.
    passed : ``In(1)``
        A step leaves the pipeline without a beat: its credit returns.
    issue : ``In(1)``
        A step is issued: it takes a credit.
    clear : ``In(1)``
        All ``depth`` credits back (between correlations; takes precedence).
    has_credit : ``Out(1)``
    surface : ``Out(stream.Signature(shape))``
    """

    def __init__(self, *, shape: ShapeLike, depth: int):
        if isinstance(depth, bool) or not isinstance(depth, int) or depth < 1:
            raise ValueError(f"depth must be a positive integer, got {depth!r}")
        self._shape, self._depth = shape, depth
        super().__init__({
            "write": In(stream.Signature(shape, always_ready=True)),
            "write_next": In(1),
            "passed": In(1),
            "issue": In(1),
            "clear": In(1),
            "has_credit": Out(1),
            "surface": Out(stream.Signature(shape)),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        ready_out, payload_out, taken = self._fifo(m)
        m.d.comb += [self.surface.valid.eq(ready_out), self.surface.payload.eq(payload_out)]
        credits = Signal(range(self._depth + 1))  # none until the first clear
        m.d.comb += self.has_credit.eq(credits != 0)
        returned = self.passed + taken
        with m.If(self.clear):
            m.d.sync += credits.eq(self._depth)
        with m.Else():
            m.d.sync += credits.eq(credits - self.issue + returned)
        return m

    def _fifo(self, m: Module) -> tuple[Value, Value, Value]:
        """A first-word-fall-through queue (as ``amaranth.lib.fifo.SyncFIFO``) whose storage is in slices
        of :data:`SLICE_BITS`, each read at a copy of its own of the read pointer.

        The read pointer reaches every storage cell (distributed RAM, read without a clock); one register
        driving them all is a chip-wide net (the critical path of 1b97a22's 4-lane build: 11.8 ns of routing
        from it to the queue's storage). The copies are loaded from the pointer's next value, so each equals it.

        Returns the queue's ``valid``, its head beat and whether the head is taken on this edge.
        """
        depth, width = self._depth, Shape.cast(self._shape).width
        level = Signal(range(depth + 1))
        produce = Signal(range(depth))
        consume = Signal(range(depth))
        readable = level != 0
        taken = readable & self.surface.ready
        written = self.write.valid  # room by construction (the credits): no check against the level

        def advanced(pointer: Value) -> Value:
            return Mux(pointer == depth - 1, 0, pointer + 1)

        consume_next = Mux(taken, advanced(consume), consume)
        m.d.sync += [consume.eq(consume_next), level.eq(level + written - taken)]
        with m.If(written):
            m.d.sync += produce.eq(advanced(produce))
        slices = [(start, min(start + SLICE_BITS, width)) for start in range(0, width, SLICE_BITS)]
        m.submodules.read_pointers = read_pointers = Replicas(consume.shape(), len(slices))
        m.d.comb += read_pointers.i.eq(consume_next)
        # The write enable too reaches every slice beside every lane's output (the critical path of 6e39ad9's
        # 4-lane build, seed 1: 8.75 ns of it one net): a copy per slice, loaded from its next value so each equals it.
        m.submodules.write_enables = write_enables = Replicas(1, len(slices))
        m.d.comb += write_enables.i.eq(self.write_next)
        head = Signal(width)
        for k, (start, stop) in enumerate(slices):
            m.submodules[f"storage{k}"] = storage = memory.Memory(shape=stop - start, depth=depth, init=[])
            write_port = storage.write_port()
            read_port = storage.read_port(domain="comb")
            m.d.comb += [
                write_port.addr.eq(produce),
                write_port.data.eq(Value.cast(self.write.payload)[start:stop]),
                write_port.en.eq(write_enables.o[k]),
                read_port.addr.eq(read_pointers.o[k]),
                head[start:stop].eq(read_port.data),
            ]
        return readable, head, taken
