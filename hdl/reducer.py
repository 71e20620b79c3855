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

Every beat passes a fixed pipeline, so that no path is longer than one comparison or one small choice
whatever the lanes: a register for the incoming beat, a compare tree for its minimum (a register per
level), the row minimum, the best fit (and the row minimum's store), the slot choice, the row-store
write. The slot choice (:class:`~lost.hdl.reducer_slots.SlotBand`) compares no row numbers: each slot
keeps whether it is needed as a flag, updated from two counters that saturate at ``r + 1``.

After the last beat is stored the reducer (:class:`~lost.hdl.reducer_scan.RunnerUpScan`) scans the row
minima (rows outside the band), then every slot (columns outside ``[bj - r, bj + r]`` of held rows inside
the band), one memory word per cycle, keeping the candidate that is smallest, then first in raster order
(one comparison of the key ``(value, i, j)``), through the same kind of lane tree. The scan takes a fixed number of cycles
whatever the data, so the cycle models stay exact (:func:`lost.model.cycles.reducer_latency`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from amaranth.hdl import Module, Mux, Signal, Value, unsigned
from amaranth.lib import data, memory, stream, wiring
from amaranth.lib.wiring import In, Out

from lost.model.cycles import reducer_geometry

from .blocks import MinimumTree, delayed
from .interface import CorrelatorParameters, checked_parameters
from .reducer_scan import RunnerUpScan, row_minimum_layout
from .reducer_slots import SlotBand

__all__ = ["BestFitReducer"]



@dataclass(frozen=True)
class _Collected:
    """What the collecting stages hand on: the beat's words and tree depth, the slot stage's inputs, the best fit."""

    in_values: Signal
    tree_levels: int
    slot_meta: Value
    slot_becomes_best: Value
    best_value: Signal
    best_i: Signal
    best_j: Signal


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
        checked_parameters(parameters)
        self._parameters = parameters
        super().__init__({
            "surface": In(stream.Signature(parameters.surface_beat, always_ready=True)),
            "best": Out(stream.Signature(parameters.best_fit_beat)),
            "busy": Out(1),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        p = self._parameters
        rows = p.surface_shape[0]
        slots, beats_per_row = reducer_geometry(p.surface_shape, p.lanes, p.exclusion_radius)
        m.submodules.row_minima = row_minima = memory.Memory(shape=row_minimum_layout(p), depth=rows, init=[])
        m.submodules.row_slots = row_slots = memory.Memory(
            shape=self._values_layout, depth=slots * beats_per_row, init=[])
        minima_write, minima_read = row_minima.write_port(), row_minima.read_port()
        slots_write, slots_read = row_slots.write_port(), row_slots.read_port()

        collected = self._collect(m, minima_write)
        slot, rows_held, in_band = self._choose_slot(m, collected)
        write_last = self._write(m, slots_write, slot, collected)
        self._answer(m, minima_read, slots_read, write_last, collected, rows_held, in_band)
        return m

    @property
    def _values_layout(self) -> data.ArrayLayout:
        return data.ArrayLayout(unsigned(self._parameters.value_bits), self._parameters.lanes)

    def _collect(self, m: Module, minima_write) -> _Collected:
        """The stages "in" to "best": a beat's minimum, its row's minimum (stored at the row's end), the best so far."""
        p = self._parameters
        value_shape = unsigned(p.value_bits)
        row_shape, col_shape = unsigned(p.row_bits), unsigned(p.col_bits)
        in_values, beat_value, beat_col, tree_meta, meta_layout, levels = self._beat_minimum(m)

        # Stage "row": this row's minimum so far (an earlier column wins ties).
        row_value, row_col = Signal(value_shape), Signal(col_shape)
        take_beat = tree_meta.first_in_row | (beat_value < row_value)
        row_value_new = Mux(take_beat, beat_value, row_value)
        row_col_new = Mux(take_beat, beat_col, row_col)
        with m.If(tree_meta.valid):
            m.d.sync += [row_value.eq(row_value_new), row_col.eq(row_col_new)]
        row_meta = delayed(m, tree_meta, meta_layout, 1, "row_meta")

        # Stage "best": at a row's end, store its minimum and compare it with the best so far.
        best_value, best_i, best_j = Signal(value_shape), Signal(row_shape), Signal(col_shape)
        row_ends = row_meta.valid & row_meta.row_end
        becomes_best = row_ends & ((row_meta.i == 0) | (row_value < best_value))
        m.d.comb += [
            minima_write.addr.eq(row_meta.i),
            minima_write.data.value.eq(row_value),
            minima_write.data.col.eq(row_col),
            minima_write.en.eq(row_ends),
        ]
        with m.If(becomes_best):
            m.d.sync += [best_value.eq(row_value), best_i.eq(row_meta.i), best_j.eq(row_col)]
        slot_meta = delayed(m, row_meta, meta_layout, 1, "slot_meta")
        slot_becomes_best = delayed(m, becomes_best, 1, 1, "slot_becomes_best")
        return _Collected(in_values=in_values, tree_levels=levels, slot_meta=slot_meta, slot_becomes_best=slot_becomes_best,
                          best_value=best_value, best_i=best_i, best_j=best_j)

    def _beat_minimum(self, m: Module) -> tuple[Signal, Value, Value, Value, data.StructLayout, int]:
        """Stage "in" and the beat's compare tree: the beat's words, its minimum and column, its metadata as they
        leave the tree, the metadata's layout and the tree's depth."""
        p = self._parameters
        cols, lanes = p.surface_shape[1], p.lanes
        value_shape = unsigned(p.value_bits)
        row_shape, col_shape = unsigned(p.row_bits), unsigned(p.col_bits)
        values_layout = self._values_layout

        # Stage "in": the transferred beat, registered before any logic.
        beat = self.surface.payload
        in_valid, in_last = Signal(), Signal()
        in_values = Signal(values_layout)
        in_count = Signal.like(beat.count)
        in_i, in_j = Signal(row_shape), Signal(col_shape)
        m.d.sync += [
            in_valid.eq(self.surface.valid),
            in_last.eq(self.surface.valid & beat.last),
            in_values.eq(beat.values),
            in_count.eq(beat.count),
            in_i.eq(beat.i),
            in_j.eq(beat.j),
        ]

        # The beat's minimum by a compare tree with a register per level (lowest lane first on ties).
        m.submodules.beat_tree = beat_tree = MinimumTree(count=lanes, key=value_shape, payload=col_shape)
        for lane in range(lanes):
            m.d.comb += [
                beat_tree.leaves[lane].valid.eq(lane < in_count),
                beat_tree.leaves[lane].key.eq(in_values[lane]),
                beat_tree.leaves[lane].payload.eq(in_j + lane),
            ]
        beat_value, beat_col = beat_tree.root.key, beat_tree.root.payload
        levels = beat_tree.latency
        meta_layout = data.StructLayout({
            "valid": 1, "last": 1, "i": row_shape, "first_in_row": 1, "row_end": 1,
        })
        in_meta = Signal(meta_layout)
        m.d.comb += [
            in_meta.valid.eq(in_valid),
            in_meta.last.eq(in_last),
            in_meta.i.eq(in_i),
            in_meta.first_in_row.eq(in_j == 0),
            in_meta.row_end.eq(in_j + in_count >= cols),
        ]
        tree_meta = delayed(m, in_meta, meta_layout, levels, "tree_meta")
        return in_values, beat_value, beat_col, tree_meta, meta_layout, levels

    def _choose_slot(self, m: Module, collected: _Collected) -> tuple[Value, list[Value], list[Value]]:
        """Stage "slot" (``SlotBand``): the slot of a row that begins; each slot's row and whether it is in the band."""
        m.submodules.slot_band = band = SlotBand(parameters=self._parameters)
        meta = collected.slot_meta
        m.d.comb += [
            band.beat.valid.eq(meta.valid),
            band.beat.first_in_row.eq(meta.first_in_row),
            band.beat.i.eq(meta.i),
            band.becomes_best.eq(collected.slot_becomes_best),
        ]
        return band.slot, list(band.rows), list(band.in_band)

    def _write(self, m: Module, slots_write, slot: Value, collected: _Collected) -> Signal:
        """Stage "write": the beat's words into its row's slot. Returns the last beat's write strobe."""
        p = self._parameters
        slots, beats_per_row = reducer_geometry(p.surface_shape, p.lanes, p.exclusion_radius)
        slot_meta = collected.slot_meta
        write_valid, write_first, write_last = Signal(), Signal(), Signal()
        write_base = Signal(range(slots * beats_per_row))
        with m.Switch(slot):
            for s in range(slots):
                with m.Case(s):
                    m.d.sync += write_base.eq(s * beats_per_row)
        m.d.sync += [
            write_valid.eq(slot_meta.valid),
            write_first.eq(slot_meta.first_in_row),
            write_last.eq(slot_meta.valid & slot_meta.last),
        ]
        write_values = delayed(m, collected.in_values, self._values_layout, collected.tree_levels + 3, "write_values")
        next_address = Signal(range(slots * beats_per_row + 1))  # the next word of the current row
        address = Mux(write_first, write_base, next_address)
        m.d.comb += [
            slots_write.addr.eq(address),
            slots_write.data.eq(write_values),
            slots_write.en.eq(write_valid),
        ]
        with m.If(write_valid):
            m.d.sync += next_address.eq(address + 1)
        return write_last

    def _answer(self, m: Module, minima_read, slots_read, write_last: Signal, collected: _Collected,
                rows_held: list[Signal], in_band: list[Signal]) -> None:
        """Scanning (``RunnerUpScan``, one memory word per cycle after the last beat is stored) and the ``best`` beat."""
        m.submodules.scan = scan = RunnerUpScan(parameters=self._parameters)
        wiring.connect(m, scan.minima_read, minima_read)
        wiring.connect(m, scan.slots_read, slots_read)
        best_taken = self.best.valid & self.best.ready
        m.d.comb += [
            scan.start.eq(write_last),
            scan.best_i.eq(collected.best_i),
            scan.best_j.eq(collected.best_j),
            *(scan.slot_rows[s].eq(row) for s, row in enumerate(rows_held)),
            *(scan.slot_in_band[s].eq(flag) for s, flag in enumerate(in_band)),
            scan.taken.eq(best_taken),
        ]

        # One register from the last beat's arrival to the best beat's transfer: the core's start and load
        # handshakes depend on it.
        busy = Signal()
        with m.If(self.surface.valid & self.surface.payload.last):
            m.d.sync += busy.eq(1)
        with m.If(best_taken):
            m.d.sync += busy.eq(0)
        m.d.comb += [
            self.best.valid.eq(scan.done),
            self.best.payload.value.eq(collected.best_value),
            self.best.payload.i.eq(collected.best_i),
            self.best.payload.j.eq(collected.best_j),
            self.best.payload.runner_up_value.eq(scan.runner.value),
            self.best.payload.runner_up_i.eq(scan.runner.i),
            self.best.payload.runner_up_j.eq(scan.runner.j),
            self.best.payload.runner_up_valid.eq(scan.runner.valid),
            self.busy.eq(busy),
        ]
