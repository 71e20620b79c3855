"""The best-fit reducer: the best fit and the runner-up of a surface, exactly as :func:`lost.model.best_fit`.

The best fit (smallest value, first in raster order) streams with constant state, but the runner-up is
the smallest value farther than ``r`` (the exclusion radius, Chebyshev) from the *final* best fit, which
is known only after the last value. The reducer therefore keeps just enough of the surface to answer
exactly once the best fit is known:

* the minimum ``(value, column)`` of every row, in a memory of ``Ho`` entries: the candidates of every
  row outside the band ``[bi - r, bi + r]`` of the final best row ``bi``;
* whole rows in ``2r + 2`` row slots (fewer when the surface has fewer rows), so that the rows of the
  final band that can hold the runner-up are held when the surface ends. A row is written into a free
  slot when it begins; a slot is needed while its row lies within ``r`` rows of the best row so far.
  While row ``c`` is written at most ``2r + 1`` earlier rows are needed, so a free slot always exists.

Why the band of the best row *so far* suffices: let the runner-up lie in row ``x`` of the final band.
If ``x`` comes after the final best row ``bi``, the band held it from its arrival. If ``x`` is ``bi``
or became the best at its end, it was held from then. Otherwise the best at the end of row ``x`` lies
in an earlier row ``y`` with a value no larger than the runner-up's, so it must lie inside the
exclusion zone of the final best (else it, being earlier in raster order, would be the runner-up);
then ``bi - r <= y < x < bi`` and every later best row ``z`` (``y < z <= bi``) keeps ``x`` within
``r`` rows, so ``x`` was held from its arrival on. (This needs ``r + 1`` slots fewer than the contract's
rolling design of ``3r + 2``.)

After the last beat the reducer scans the row minima (rows outside the band), then every slot (columns
outside ``[bj - r, bj + r]`` of held rows inside the band), one memory word per cycle, keeping the
candidate that is smallest, then first in raster order. The scan takes a fixed number of cycles
whatever the data, so the cycle models stay exact (:func:`lost.model.cycles.reducer_latency`).
"""

from __future__ import annotations

from typing import Any

from amaranth.hdl import Const, Module, Mux, Signal, unsigned
from amaranth.lib import data, memory, stream, wiring
from amaranth.lib.wiring import In, Out

from lost.model.cycles import reducer_geometry

from .interface import CorrelatorParameters

__all__ = ["BestFitReducer"]


class BestFitReducer(wiring.Component):
    """Watch a surface's beats; emit its best fit and runner-up.

    The reducer observes transfers: it takes a beat on every cycle ``surface.valid`` is high and never
    applies back-pressure (``surface`` is ``always_ready``); a core drives ``surface.valid`` with the
    transfers of its own surface stream. Beats must arrive in raster order, the first at ``(0, 0)``,
    the last with ``last`` set; no beat may arrive while ``busy``.

    Latency: with ``L = reducer_latency(...)`` (:func:`lost.model.cycles.reducer_latency`), the ``best``
    beat is offered from edge ``L - 1`` after the one on which the last surface beat arrived, and
    transfers on edge ``L`` after it when ``best.ready`` is high.

    Parameters
    ----------
    parameters : CorrelatorParameters
        The core's parameters: surface shape, lanes, widths and exclusion radius.

    Members
    -------
    surface : ``In(stream.Signature(SurfaceBeat(...), always_ready=True))``
        The transferred surface beats.
    best : ``Out(stream.Signature(BestFitBeat(...)))``
        One beat per surface.
    busy : ``Out(1)``
        Between the last surface beat and the transfer of the best beat.
    """

    def __init__(self, *, parameters: CorrelatorParameters):
        if not isinstance(parameters, CorrelatorParameters):
            raise ValueError(f"parameters must be a CorrelatorParameters, got {parameters!r}")
        self._parameters = parameters
        super().__init__({
            "surface": In(stream.Signature(parameters.surface_beat, always_ready=True)),
            "best": Out(stream.Signature(parameters.best_fit_beat)),
            "busy": Out(1),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        p = self._parameters
        rows, cols = p.surface_shape
        lanes, r = p.lanes, p.exclusion_radius
        slots, beats_per_row = reducer_geometry(p.surface_shape, lanes, r)
        value_shape = unsigned(p.value_bits)
        row_shape, col_shape = unsigned(p.row_bits), unsigned(p.col_bits)

        row_minimum_layout = data.StructLayout({"value": value_shape, "col": col_shape})
        m.submodules.row_minima = row_minima = memory.Memory(shape=row_minimum_layout, depth=rows, init=[])
        m.submodules.row_slots = row_slots = memory.Memory(
            shape=data.ArrayLayout(value_shape, lanes), depth=slots * beats_per_row, init=[])
        minima_write, minima_read = row_minima.write_port(), row_minima.read_port()
        slots_write, slots_read = row_slots.write_port(), row_slots.read_port()

        # --- collecting: one beat per cycle --------------------------------------------------------
        beat = self.surface.payload
        arrive = self.surface.valid

        # The beat's minimum, lowest lane first on ties.
        beat_value = Signal(value_shape)
        beat_col = Signal(col_shape)
        chosen_value, chosen_lane = beat.values[0], Const(0, range(lanes))
        for lane in range(1, lanes):
            take = (lane < beat.count) & (beat.values[lane] < chosen_value)
            chosen_value = Mux(take, beat.values[lane], chosen_value)
            chosen_lane = Mux(take, lane, chosen_lane)
        m.d.comb += [beat_value.eq(chosen_value), beat_col.eq(beat.j + chosen_lane)]

        first_in_row = beat.j == 0
        row_end = beat.j + beat.count >= cols
        row_value, row_col = Signal(value_shape), Signal(col_shape)  # this row's minimum so far
        row_value_new, row_col_new = Signal(value_shape), Signal(col_shape)
        with m.If(first_in_row | (beat_value < row_value)):
            m.d.comb += [row_value_new.eq(beat_value), row_col_new.eq(beat_col)]
        with m.Else():
            m.d.comb += [row_value_new.eq(row_value), row_col_new.eq(row_col)]

        best_value, best_i, best_j = Signal(value_shape), Signal(row_shape), Signal(col_shape)

        # Slot bookkeeping: which row each slot holds.
        tag = [Signal(row_shape, name=f"slot{s}_row") for s in range(slots)]
        held = [Signal(name=f"slot{s}_held") for s in range(slots)]
        needed = [held[s] & (tag[s] + r >= best_i) & (tag[s] <= best_i + r)
                  for s in range(slots)]
        free_slot = Signal(range(slots))
        for s in reversed(range(slots)):
            with m.If(~needed[s]):
                m.d.comb += free_slot.eq(s)
        first_beat = first_in_row & (beat.i == 0)
        slot = Signal(range(slots))
        m.d.comb += slot.eq(Mux(first_beat, 0, free_slot))
        row_base = Signal(range(slots * beats_per_row + 1))
        m.d.comb += row_base.eq(slot * beats_per_row)
        next_address = Signal(range(slots * beats_per_row + 1))  # the next beat of the current row
        address = Mux(first_in_row, row_base, next_address)

        m.d.comb += [
            slots_write.addr.eq(address),
            slots_write.data.eq(beat.values),
            slots_write.en.eq(arrive),
            minima_write.addr.eq(beat.i),
            minima_write.data.value.eq(row_value_new),
            minima_write.data.col.eq(row_col_new),
            minima_write.en.eq(arrive & row_end),
        ]

        # --- scanning: one memory word per cycle after the last beat ------------------------------
        scan_rows_end = rows
        scan_end = rows + slots * beats_per_row
        scanning, done = Signal(), Signal()
        step = Signal(range(scan_end + 1))
        slot_index = Signal(range(slots))
        slot_beat = Signal(range(beats_per_row))
        # What the memories' data registers hold this cycle: the word read for the previous step.
        seen = Signal()
        seen_row_minimum = Signal()
        seen_slot = Signal(range(slots))
        seen_beat = Signal(range(beats_per_row))
        seen_row = Signal(row_shape)

        m.d.comb += [
            minima_read.addr.eq(step),
            slots_read.addr.eq(step - scan_rows_end),
        ]

        runner_value, runner_i, runner_j = Signal(value_shape), Signal(row_shape), Signal(col_shape)
        runner_valid = Signal()

        def better(value, i, j):
            """Whether (value, i, j) beats the runner-up so far: smaller, then first in raster order."""
            return (~runner_valid | (value < runner_value)
                    | ((value == runner_value) & ((i < runner_i) | ((i == runner_i) & (j < runner_j)))))

        def outside(index, centre):
            return (index + r < centre) | (index > centre + r)

        # Candidate from a row minimum: the row lies outside the band.
        minimum = minima_read.data
        row_candidate = seen_row_minimum & outside(seen_row, best_i)
        # Candidate from a slot word: the slot holds a row of the band; columns outside [bj-r, bj+r].
        slot_row = Signal(row_shape)
        slot_in_band = Signal()
        for s in range(slots):
            with m.If(seen_slot == s):
                m.d.comb += [
                    slot_row.eq(tag[s]),
                    slot_in_band.eq(held[s] & ~outside(tag[s], best_i)),
                ]
        lane_value, lane_col, lane_found = Const(0, value_shape), Const(0, col_shape), Const(0, 1)
        for lane in range(lanes):
            col = seen_beat * lanes + lane
            ok = (col < cols) & outside(col, best_j)
            take = ok & (~lane_found | (slots_read.data[lane] < lane_value))
            lane_value = Mux(take, slots_read.data[lane], lane_value)
            lane_col = Mux(take, col, lane_col)
            lane_found = lane_found | ok
        slot_candidate = ~seen_row_minimum & slot_in_band & lane_found

        candidate_value = Mux(seen_row_minimum, minimum.value, lane_value)
        candidate_i = Mux(seen_row_minimum, seen_row, slot_row)
        candidate_j = Mux(seen_row_minimum, minimum.col, lane_col)
        with m.If(seen & (row_candidate | slot_candidate) & better(candidate_value, candidate_i, candidate_j)):
            m.d.sync += [
                runner_value.eq(candidate_value),
                runner_i.eq(candidate_i),
                runner_j.eq(candidate_j),
                runner_valid.eq(1),
            ]

        m.d.comb += [
            self.best.valid.eq(done),
            self.best.payload.value.eq(best_value),
            self.best.payload.i.eq(best_i),
            self.best.payload.j.eq(best_j),
            self.best.payload.runner_up_value.eq(runner_value),
            self.best.payload.runner_up_i.eq(runner_i),
            self.best.payload.runner_up_j.eq(runner_j),
            self.best.payload.runner_up_valid.eq(runner_valid),
            self.busy.eq(scanning | seen | done),
        ]

        # --- state -------------------------------------------------------------------------------
        with m.If(arrive):
            m.d.sync += [
                row_value.eq(row_value_new),
                row_col.eq(row_col_new),
                next_address.eq(address + 1),
            ]
            with m.If(first_in_row):
                for s in range(slots):
                    with m.If(slot == s):
                        m.d.sync += [tag[s].eq(beat.i), held[s].eq(1)]
                    with m.Elif(first_beat):
                        m.d.sync += held[s].eq(0)
            with m.If(row_end & ((beat.i == 0) | (row_value_new < best_value))):
                m.d.sync += [best_value.eq(row_value_new), best_i.eq(beat.i), best_j.eq(row_col_new)]
            with m.If(beat.last):
                m.d.sync += [scanning.eq(1), step.eq(0), runner_valid.eq(0), seen.eq(0)]

        with m.If(scanning):
            m.d.sync += [
                seen.eq(1),
                seen_row_minimum.eq(step < scan_rows_end),
                seen_row.eq(step),
                seen_slot.eq(slot_index),
                seen_beat.eq(slot_beat),
                step.eq(step + 1),
            ]
            with m.If(step >= scan_rows_end):
                with m.If(slot_beat == beats_per_row - 1):
                    m.d.sync += [slot_beat.eq(0), slot_index.eq(slot_index + 1)]
                with m.Else():
                    m.d.sync += slot_beat.eq(slot_beat + 1)
            with m.If(step == scan_end - 1):
                m.d.sync += scanning.eq(0)
        with m.Elif(seen):
            # The last word was evaluated this cycle; the runner-up is final on the next.
            m.d.sync += [seen.eq(0), done.eq(1)]
        with m.If(self.best.valid & self.best.ready):
            m.d.sync += done.eq(0)
        with m.If(arrive & beat.last):
            m.d.sync += [slot_index.eq(0), slot_beat.eq(0)]

        return m

