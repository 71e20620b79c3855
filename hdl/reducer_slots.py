"""The best-fit reducer's slot band: which row slot a beginning row is written into, and which slots are needed."""

from __future__ import annotations

from typing import Any

from amaranth.hdl import Module, Mux, Signal, unsigned
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In, Out

from lost.hdl.interface import CorrelatorParameters, checked_parameters
from lost.model.cycles import reducer_geometry

__all__ = ["SlotBand"]


class SlotBand(wiring.Component):
    """The row slots' bookkeeping: each slot's row, whether it lies in the band of the best row so far, a free slot.

    Beats arrive in raster order (a surface's first at row 0, a new surface beginning again at row 0);
    ``becomes_best`` comes with the last beat of a row that becomes the best so far (row 0's always does).
    A slot is needed (``in_band``) while its row lies within ``r`` rows of the best row so far; the
    reducer holds a row only in such a slot. Rather than comparing row numbers, each slot keeps that as
    a flag, kept exact from two small counters that saturate at ``r + 1``: the slot's age (rows begun
    since its row) and the rows begun since the best row. A row that begins is in the band when fewer
    than ``r`` rows began since the best row (row 0 always); a new best row keeps exactly the slots of
    the last ``r + 1`` rows begun, its own included; row 0 frees every other slot. At most ``2r + 1``
    earlier rows are needed while a row begins, and there are ``min(2r + 2, Ho)`` slots, so a free slot
    always exists.

    Latency: ``slot`` is combinational, for the beat in the same cycle (the lowest slot not in the band;
    0 for row 0). A beat and ``becomes_best`` in the cycle ending on edge ``e`` are reflected in ``rows``
    and ``in_band`` from edge ``e`` on.

    Parameters
    ----------
    parameters : CorrelatorParameters
        The surface shape, lanes and exclusion radius (:func:`lost.model.cycles.reducer_geometry`).

    Members
    -------
    beat : ``In(StructLayout({"valid": 1, "first_in_row": 1, "i": unsigned(row_bits)}))``
        The slot stage's beat; a row begins with a valid beat at ``first_in_row``.
    becomes_best : ``In(1)``
    slot : ``Out(range(slots))``
        The slot a row beginning with this beat is written into.
    rows : ``Out(unsigned(row_bits)).array(slots)``
        The row each slot holds.
    in_band : ``Out(1).array(slots)``
        The slot holds a row within ``r`` rows of the best row so far.
    """

    def __init__(self, *, parameters: CorrelatorParameters):
        checked_parameters(parameters)
        self._parameters = p = parameters
        self.slots, _ = reducer_geometry(p.surface_shape, p.lanes, p.exclusion_radius)
        row_shape = unsigned(p.row_bits)
        self.beat_layout = data.StructLayout({"valid": 1, "first_in_row": 1, "i": row_shape})
        super().__init__({
            "beat": In(self.beat_layout),
            "becomes_best": In(1),
            "slot": Out(range(self.slots)),
            "rows": Out(row_shape).array(self.slots),
            "in_band": Out(1).array(self.slots),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        r, slots = self._parameters.exclusion_radius, self.slots
        beat, becomes_best = self.beat, self.becomes_best
        tag = [Signal.like(self.rows[s], name=f"slot{s}_row") for s in range(slots)]
        held = [Signal(name=f"slot{s}_held") for s in range(slots)]
        age = [Signal(range(r + 2), name=f"slot{s}_age") for s in range(slots)]
        in_band = [Signal(name=f"slot{s}_in_band") for s in range(slots)]
        since_best = Signal(range(r + 2))
        free_slot = Signal(range(slots))
        for s in reversed(range(slots)):
            with m.If(~in_band[s]):
                m.d.comb += free_slot.eq(s)
        first_beat = beat.first_in_row & (beat.i == 0)
        slot = Mux(first_beat, 0, free_slot)
        begins = beat.valid & beat.first_in_row
        held_next = [Signal(name=f"slot{s}_held_next") for s in range(slots)]
        age_next = [Signal(range(r + 2), name=f"slot{s}_age_next") for s in range(slots)]
        band_next = [Signal(name=f"slot{s}_in_band_next") for s in range(slots)]
        for s in range(slots):
            chosen = begins & (slot == s)
            m.d.comb += [
                held_next[s].eq(Mux(chosen, 1, held[s] & ~(begins & first_beat))),
                age_next[s].eq(Mux(chosen, 0, Mux(begins & (age[s] <= r), age[s] + 1, age[s]))),
                # A row that begins lies within r rows of the best so far when fewer than r rows began
                # since; a new best row keeps exactly the rows of the last r + 1.
                band_next[s].eq(Mux(becomes_best, held_next[s] & (age_next[s] <= r),
                                    Mux(chosen, first_beat | (since_best < r),
                                        in_band[s] & ~(begins & first_beat)))),
            ]
            m.d.sync += [held[s].eq(held_next[s]), age[s].eq(age_next[s]), in_band[s].eq(band_next[s])]
            with m.If(chosen):
                m.d.sync += tag[s].eq(beat.i)
        with m.If(becomes_best | (begins & first_beat)):
            m.d.sync += since_best.eq(0)
        with m.Elif(begins & (since_best <= r)):
            m.d.sync += since_best.eq(since_best + 1)
        m.d.comb += [
            self.slot.eq(slot),
            *(self.rows[s].eq(tag[s]) for s in range(slots)),
            *(self.in_band[s].eq(in_band[s]) for s in range(slots)),
        ]
        return m
