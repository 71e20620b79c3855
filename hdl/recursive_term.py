"""The recursive core's term unit: one absolute difference and one accumulator, in clocked stages."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from typing import Any

from amaranth.hdl import Module, Mux, Shape, Signal, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out

from lost.hdl.blocks import DelayLine
from lost.hdl.interface import CorrelatorParameters, checked_parameters

__all__ = ["RecursiveShapes", "TermStage", "TermUnit"]


class TermStage(IntEnum):
    """The term unit's clocked stages, in order; each value is the stage's number of registers from the step."""

    TERM = 1        # what the term subtracts (C + Msum); the window memory's read on this edge
    FETCHED = 2     # the window word, registered as it leaves the block RAM
    PRODUCT = 3     # f * M
    MAGNITUDE = 4   # f * M - C - Msum
    ACCUMULATE = 5  # its absolute value, added on the next edge


@dataclass(frozen=True)
class RecursiveShapes:
    """The shapes of the recursive core's quantities (a plain term is wider than the centred bound for n = 1)."""

    centred: Shape   # a node's centred depth C: n * S - Ssum with mean compensation, S without
    scaled: Shape    # f * S or f * M
    offset: Shape    # C + Msum, what a term subtracts from f * M
    term: Shape      # f * M - C - Msum
    magnitude: Shape
    accumulator: Shape

    @classmethod
    def of(cls, p: CorrelatorParameters) -> RecursiveShapes:
        widths = p.widths
        centred = signed(max(widths.centred_depth.bits, widths.depth.bits))
        return cls(
            centred=centred,
            scaled=signed(max(widths.scaled_depth.bits, widths.depth.bits)),
            offset=signed(max(centred.width, widths.window_sum.bits) + 1),
            term=signed(max(widths.term.bits, widths.difference.bits)),
            magnitude=unsigned(max(widths.abs_term.bits, widths.abs_difference.bits)),
            accumulator=unsigned(widths.accumulator.bits),
        )


class TermUnit(wiring.Component):
    """``sum |f * M - offset|`` over each placement's terms, one term per clock, and the placement's value.

    A term is taken on an edge when ``advance`` is high: ``term`` (its flags and ``offset``) on that
    edge, its map word ``word`` in the cycle after it (a synchronous memory read on the same edge; the
    word must hold until the next term is taken). The stages (:class:`TermStage`) then register the
    word (a block RAM's output is slow), form ``f * M`` (the multiplier between registers), subtract the
    offset, take the absolute value and accumulate: one carry chain per clock. With ``empty`` every term
    is zero (a patch without a valid node).

    Only a placement's last term needs the output register; while that is still full and not taken,
    every stage holds and ``advance`` is low.

    Latency: a placement's last term taken on edge ``e`` (with ``value.ready`` high throughout) makes
    ``value.valid`` high from edge ``e + 5`` (:data:`TermStage.ACCUMULATE` + 1) until the edge it transfers on.

    Parameters
    ----------
    parameters : CorrelatorParameters

    Members
    -------
    term : ``In(StructLayout({"valid": 1, "first": 1, "last": 1, "offset": offset}))``
        ``valid`` low: a bubble (a step of the flush round, or no step).
    word : ``In(signed(depth_bits))``
    factor : ``In(unsigned)``
        ``f``, still through the correlation.
    empty : ``In(1)``
    advance : ``Out(1)``
        The unit takes a term (or a bubble) on this edge.
    value : ``Out(stream.Signature(unsigned(accumulator_bits)))``
    """

    def __init__(self, *, parameters: CorrelatorParameters):
        checked_parameters(parameters)
        self._parameters = p = parameters
        self.shapes = s = RecursiveShapes.of(p)
        h, w = p.patch_shape
        self.term_layout = data.StructLayout({"valid": 1, "first": 1, "last": 1, "offset": s.offset})
        super().__init__({
            "term": In(self.term_layout),
            "word": In(signed(p.depth_bits)),
            "factor": In(range(h * w + 1)),
            "empty": In(1),
            "advance": Out(1),
            "value": Out(stream.Signature(s.accumulator)),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        p, s = self._parameters, self.shapes
        # Which term each stage holds (a placement's first or last), through the stages in order.
        flags_layout = data.StructLayout({"valid": 1, "first": 1, "last": 1})
        m.submodules.flags = flags = DelayLine(flags_layout, TermStage.ACCUMULATE, enable=True)
        m.submodules.offsets = offsets = DelayLine(s.offset, TermStage.PRODUCT, enable=True)
        fetched_word = Signal(signed(p.depth_bits))
        product_word = Signal(s.scaled)
        magnitude_term = Signal(s.term)
        abs_term = Signal(s.magnitude)
        accumulator = Signal(s.accumulator)
        out_value = Signal(s.accumulator)
        out_full = Signal()

        accumulate = flags.o  # the flags at the accumulate stage
        accumulator_new = Mux(accumulate.first, 0, accumulator) + abs_term
        hold = accumulate.valid & accumulate.last & out_full & ~self.value.ready
        m.d.comb += [
            self.advance.eq(~hold),
            flags.en.eq(~hold),
            offsets.en.eq(~hold),
            flags.i.valid.eq(self.term.valid),
            flags.i.first.eq(self.term.first),
            flags.i.last.eq(self.term.last),
            offsets.i.eq(self.term.offset),
        ]
        with m.If(~hold):
            m.d.sync += [
                fetched_word.eq(self.word),
                product_word.eq(self.factor * fetched_word),
                # f * M - C - Msum = n * (M - S) - (Msum - Ssum) with mean compensation; M - S without.
                magnitude_term.eq(product_word - offsets.o),
                abs_term.eq(Mux(self.empty, 0, abs(magnitude_term))),
            ]
            with m.If(accumulate.valid):
                m.d.sync += accumulator.eq(accumulator_new)

        m.d.comb += [self.value.valid.eq(out_full), self.value.payload.eq(out_value)]
        with m.If(self.value.valid & self.value.ready):
            m.d.sync += out_full.eq(0)
        with m.If(~hold & accumulate.valid & accumulate.last):
            m.d.sync += [out_value.eq(accumulator_new), out_full.eq(1)]
        return m
