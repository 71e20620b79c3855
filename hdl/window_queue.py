"""The window correlator's output queue, and the credits that keep its pipeline from ever stalling."""

from __future__ import annotations

from typing import Any

from amaranth.hdl import Module, Shape, ShapeLike, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.fifo import SyncFIFO
from amaranth.lib.wiring import In, Out

__all__ = ["CreditQueue"]


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
        A beat into the queue (there is room by construction).
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
            "passed": In(1),
            "issue": In(1),
            "clear": In(1),
            "has_credit": Out(1),
            "surface": Out(stream.Signature(shape)),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        m.submodules.fifo = fifo = SyncFIFO(width=Shape.cast(self._shape).width, depth=self._depth)
        m.d.comb += [
            fifo.w_data.eq(self.write.payload),
            fifo.w_en.eq(self.write.valid),
            self.surface.valid.eq(fifo.r_rdy),
            self.surface.payload.eq(fifo.r_data),
            fifo.r_en.eq(self.surface.ready),
        ]
        credits = Signal(range(self._depth + 1))  # none until the first clear
        m.d.comb += self.has_credit.eq(credits != 0)
        returned = self.passed + (fifo.r_rdy & fifo.r_en)
        with m.If(self.clear):
            m.d.sync += credits.eq(self._depth)
        with m.Else():
            m.d.sync += credits.eq(credits - self.issue + returned)
        return m
