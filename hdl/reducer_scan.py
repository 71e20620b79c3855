"""The best-fit reducer's scan: the runner-up, from the row minima and the held rows, once the best fit is final."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from amaranth.hdl import Cat, Module, Mux, Signal, Value, unsigned
from amaranth.lib import data, memory, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import ceil_log2

from lost.hdl.blocks import MinimumTree, delayed, tree_levels
from lost.hdl.interface import CorrelatorParameters, checked_parameters
from lost.model.cycles import reducer_geometry

__all__ = ["RunnerUpScan", "row_minimum_layout"]


def row_minimum_layout(p: CorrelatorParameters) -> data.StructLayout:
    """A row's minimum: its value and its column (the first of equal values)."""
    return data.StructLayout({"value": unsigned(p.value_bits), "col": unsigned(p.col_bits)})



@dataclass(frozen=True)
class _Scan:
    """The scan's position (set by :meth:`RunnerUpScan._sequence`) and what the memories' data registers hold."""

    scanning: Signal
    step: Signal
    slot_index: Signal
    slot_col: Signal
    seen: Signal
    seen_final: Signal
    seen_row_minimum: Signal
    seen_slot: Signal
    seen_cols: list
    seen_row: Signal


class RunnerUpScan(wiring.Component):
    """Read every row minimum, then every word of every row slot, one a cycle; keep the smallest candidate.

    A row minimum is a candidate when its row lies outside the band ``[bi - r, bi + r]`` of the best
    fit; a slot word's lane when its slot holds a row of the band (``slot_in_band``) and its column lies
    outside ``[bj - r, bj + r]``. Candidates are keyed ``(value, i, j)``: the smallest key is the
    smallest value, then the first in raster order. The memories' outputs are registered before any
    logic (a block RAM's clock-to-output alone is half a 100 MHz period on the ECP5), the candidates
    too, then a :class:`~lost.hdl.blocks.MinimumTree` over the lanes.

    Latency: the scan takes ``rows + slots * beats_per_row`` cycles whatever the data; with ``start``
    high in the cycle ending on edge 0, ``done`` is high from edge ``rows + slots * beats_per_row +
    ceil(log2(lanes)) + 3`` until the edge after ``taken``; ``runner`` is final from then. ``best_i``,
    ``best_j`` and the slots must hold from edge 0 on.

    Parameters
    ----------
    parameters : CorrelatorParameters

    Members
    -------
    start : ``In(1)``
    best_i, best_j : ``In(unsigned(row_bits))``, ``In(unsigned(col_bits))``
    slot_rows : ``In(unsigned(row_bits)).array(slots)``
        The row each slot holds.
    slot_in_band : ``In(1).array(slots)``
        The slot holds a row of the band.
    minima_read : ``In(memory.ReadPort.Signature(...))``
        The row minima: :func:`row_minimum_layout` words, one per surface row.
    slots_read : ``In(memory.ReadPort.Signature(...))``
        The row slots: ``slots * beats_per_row`` words of ``lanes`` values, slot by slot.
    taken : ``In(1)``
        The answer transferred.
    runner : ``Out(StructLayout({"valid": 1, "value": ..., "i": ..., "j": ...}))``
    done : ``Out(1)``
    """

    def __init__(self, *, parameters: CorrelatorParameters):
        checked_parameters(parameters)
        self._parameters = p = parameters
        rows, _ = p.surface_shape
        self.slots, self.beats_per_row = reducer_geometry(p.surface_shape, p.lanes, p.exclusion_radius)
        row_shape, col_shape = unsigned(p.row_bits), unsigned(p.col_bits)
        self.values_layout = data.ArrayLayout(unsigned(p.value_bits), p.lanes)
        super().__init__({
            "start": In(1),
            "best_i": In(row_shape),
            "best_j": In(col_shape),
            "slot_rows": In(row_shape).array(self.slots),
            "slot_in_band": In(1).array(self.slots),
            "minima_read": In(memory.ReadPort.Signature(addr_width=ceil_log2(rows), shape=row_minimum_layout(p))),
            "slots_read": In(memory.ReadPort.Signature(addr_width=ceil_log2(self.slots * self.beats_per_row),
                                                       shape=self.values_layout)),
            "taken": In(1),
            "runner": Out(data.StructLayout({"valid": 1, "value": unsigned(p.value_bits), "i": row_shape,
                                             "j": col_shape})),
            "done": Out(1),
        })

    @property
    def latency(self) -> int:
        """Edges from ``start`` to ``done``."""
        rows, _ = self._parameters.surface_shape
        return rows + self.slots * self.beats_per_row + tree_levels(self._parameters.lanes) + 3

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        scan = self._reads(m)
        band_rows, band_cols = self._band(m)
        candidate_ok, candidate_key, candidate_final = self._candidates(m, scan, band_rows, band_cols)
        runner_valid = self._runner(m, candidate_ok, candidate_key)
        self._sequence(m, scan, runner_valid, candidate_final)
        return m

    def _reads(self, m: Module) -> _Scan:
        """The scan's position, the memories' addresses, and what their data registers hold (``seen_*``)."""
        p = self._parameters
        rows, _ = p.surface_shape
        scan_end = rows + self.slots * self.beats_per_row
        scanning = Signal()
        step = Signal(range(scan_end + 1))
        slot_index = Signal(range(self.slots))
        slot_col = Signal(range(self.beats_per_row * p.lanes + 1))  # the first column of the word read
        m.d.comb += [
            self.minima_read.addr.eq(step),
            self.minima_read.en.eq(1),
            self.slots_read.addr.eq(step - rows),
            self.slots_read.en.eq(1),
        ]
        # What the memories' data registers hold this cycle: the word read for the previous step.
        seen, seen_final = Signal(), Signal()
        seen_row_minimum = Signal()
        seen_slot = Signal(range(self.slots))
        seen_cols = [Signal.like(slot_col, name=f"seen_col{lane}") for lane in range(p.lanes)]
        seen_row = Signal(unsigned(p.row_bits))
        return _Scan(scanning, step, slot_index, slot_col, seen, seen_final, seen_row_minimum, seen_slot, seen_cols,
                     seen_row)

    def _band(self, m: Module) -> tuple[tuple[Signal, Signal], tuple[Signal, Signal]]:
        """The band's bounds, registered (the best fit is final before the scan starts): rows, columns."""
        p, r = self._parameters, self._parameters.exclusion_radius
        rows, cols = p.surface_shape
        band_rows = Signal(range(-r, rows)), Signal(range(rows + r))
        band_cols = Signal(range(-r, cols)), Signal(range(cols + r))
        m.d.sync += [
            band_rows[0].eq(self.best_i - r), band_rows[1].eq(self.best_i + r),
            band_cols[0].eq(self.best_j - r), band_cols[1].eq(self.best_j + r),
        ]
        return band_rows, band_cols

    def _candidates(self, m: Module, scan: _Scan, band_rows: tuple, band_cols: tuple) -> tuple[Value, Value, Value]:
        """The fetched words' candidates, registered, then their smallest key (:class:`MinimumTree`).

        Returns whether there is one, its key, and whether the scan's last word reaches the runner-up.
        """
        p = self._parameters
        _, cols = p.surface_shape
        lanes, row_shape = p.lanes, unsigned(p.row_bits)

        def outside(index, band):
            return (index < band[0]) | (index > band[1])

        fetched, fetched_final = delayed(m, scan.seen, 1, 1, "fetched"), delayed(m, scan.seen_final, 1, 1, "fetched_final")
        fetched_row_minimum = delayed(m, scan.seen_row_minimum, 1, 1, "fetched_row_minimum")
        fetched_slot = delayed(m, scan.seen_slot, scan.seen_slot.shape(), 1, "fetched_slot")
        fetched_cols = [delayed(m, seen_col, seen_col.shape(), 1, f"fetched_col{lane}")
                        for lane, seen_col in enumerate(scan.seen_cols)]
        fetched_row = delayed(m, scan.seen_row, row_shape, 1, "fetched_row")
        fetched_minimum = delayed(m, self.minima_read.data, row_minimum_layout(p), 1, "fetched_minimum")
        fetched_words = delayed(m, self.slots_read.data, self.values_layout, 1, "fetched_words")

        key_shape = unsigned(p.value_bits + p.row_bits + p.col_bits)
        slot_row = Signal(row_shape)
        slot_in_band = Signal()
        with m.Switch(fetched_slot):
            for s in range(self.slots):
                with m.Case(s):
                    m.d.comb += [slot_row.eq(self.slot_rows[s]), slot_in_band.eq(self.slot_in_band[s])]
        candidates = []
        for lane in range(lanes):
            col = fetched_cols[lane]
            slot_ok = ~fetched_row_minimum & slot_in_band & (col < cols) & outside(col, band_cols)
            key = Cat(col[:p.col_bits], slot_row, fetched_words[lane])
            if lane == 0:
                row_ok = fetched_row_minimum & outside(fetched_row, band_rows)
                key = Mux(fetched_row_minimum, Cat(fetched_minimum.col, fetched_row, fetched_minimum.value), key)
                candidates.append((fetched & (row_ok | slot_ok), key))
            else:
                candidates.append((fetched & slot_ok, key))
        # Registered before the tree (a register per candidate), then the smallest key (keys are distinct).
        m.submodules.candidate_tree = candidate_tree = MinimumTree(count=lanes, key=key_shape)
        for lane, (ok, key) in enumerate(candidates):
            leaf = Signal(candidate_tree.item, name=f"leaf{lane}")
            m.d.sync += [leaf.valid.eq(ok), leaf.key.eq(key)]
            m.d.comb += candidate_tree.leaves[lane].eq(leaf)
        candidate_final = delayed(m, fetched & fetched_final, 1, candidate_tree.latency + 1, "candidate_final")
        return candidate_tree.root.valid, candidate_tree.root.key, candidate_final

    def _runner(self, m: Module, candidate_ok: Value, candidate_key: Value) -> Signal:
        """The smallest candidate so far, the ``runner`` output; returns its valid bit (the scan clears it)."""
        p = self._parameters
        runner_key = Signal(unsigned(p.value_bits + p.row_bits + p.col_bits))
        runner_valid = Signal()
        with m.If(candidate_ok & (~runner_valid | (candidate_key < runner_key))):
            m.d.sync += [runner_key.eq(candidate_key), runner_valid.eq(1)]
        m.d.comb += [
            self.runner.valid.eq(runner_valid),
            self.runner.value.eq(runner_key[p.row_bits + p.col_bits:]),
            self.runner.i.eq(runner_key[p.col_bits:p.row_bits + p.col_bits]),
            self.runner.j.eq(runner_key[:p.col_bits]),
        ]
        return runner_valid

    def _sequence(self, m: Module, scan: _Scan, runner_valid: Signal, candidate_final: Value) -> None:
        """The scan's steps: the row minima, then every slot word; ``done`` once the last word is counted."""
        p = self._parameters
        rows, _ = p.surface_shape
        lanes, beats_per_row = p.lanes, self.beats_per_row
        scan_rows_end = rows
        scan_end = rows + self.slots * beats_per_row
        step, slot_col, slot_index = scan.step, scan.slot_col, scan.slot_index
        with m.If(self.start):
            m.d.sync += [scan.scanning.eq(1), step.eq(0), runner_valid.eq(0), slot_index.eq(0), slot_col.eq(0)]
        m.d.sync += scan.seen.eq(scan.scanning)
        with m.If(scan.scanning):
            m.d.sync += [
                scan.seen_final.eq(step == scan_end - 1),
                scan.seen_row_minimum.eq(step < scan_rows_end),
                scan.seen_row.eq(step),
                scan.seen_slot.eq(slot_index),
                *(seen_col.eq(slot_col + lane) for lane, seen_col in enumerate(scan.seen_cols)),
                step.eq(step + 1),
            ]
            with m.If(step >= scan_rows_end):
                with m.If(slot_col == (beats_per_row - 1) * lanes):
                    m.d.sync += [slot_col.eq(0), slot_index.eq(slot_index + 1)]
                with m.Else():
                    m.d.sync += slot_col.eq(slot_col + lanes)
            with m.If(step == scan_end - 1):
                m.d.sync += scan.scanning.eq(0)
        done = Signal()
        with m.If(candidate_final):
            # The last word reaches the runner-up on this edge; it is final on the next.
            m.d.sync += done.eq(1)
        with m.If(self.taken):
            m.d.sync += done.eq(0)
        m.d.comb += self.done.eq(done)
