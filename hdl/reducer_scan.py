"""The best-fit reducer's scan: the runner-up, from the row minima and the held rows, once the best fit is final."""

from __future__ import annotations

from typing import Any

from amaranth.hdl import Cat, Module, Mux, Signal, unsigned
from amaranth.lib import data, memory, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import ceil_log2

from lost.hdl.blocks import DelayLine, MinimumTree, tree_levels
from lost.hdl.interface import CorrelatorParameters
from lost.model.cycles import reducer_geometry

__all__ = ["RunnerUpScan", "row_minimum_layout"]


def row_minimum_layout(p: CorrelatorParameters) -> data.StructLayout:
    """A row's minimum: its value and its column (the first of equal values)."""
    return data.StructLayout({"value": unsigned(p.value_bits), "col": unsigned(p.col_bits)})


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
        if not isinstance(parameters, CorrelatorParameters):
            raise ValueError(f"parameters must be a CorrelatorParameters, got {parameters!r}")
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
        p = self._parameters
        rows, cols = p.surface_shape
        lanes, r = p.lanes, p.exclusion_radius
        slots, beats_per_row = self.slots, self.beats_per_row
        row_shape = unsigned(p.row_bits)

        def delayed(value, shape, cycles, name):
            m.submodules[name] = line = DelayLine(shape, cycles)
            m.d.comb += line.i.eq(value)
            return line.o

        scan_rows_end = rows
        scan_end = rows + slots * beats_per_row
        scanning = Signal()
        step = Signal(range(scan_end + 1))
        slot_index = Signal(range(slots))
        slot_col = Signal(range(beats_per_row * lanes + 1))  # the first column of the word read
        m.d.comb += [
            self.minima_read.addr.eq(step),
            self.minima_read.en.eq(1),
            self.slots_read.addr.eq(step - scan_rows_end),
            self.slots_read.en.eq(1),
        ]
        # What the memories' data registers hold this cycle: the word read for the previous step.
        seen, seen_final = Signal(), Signal()
        seen_row_minimum = Signal()
        seen_slot = Signal(range(slots))
        seen_cols = [Signal.like(slot_col, name=f"seen_col{lane}") for lane in range(lanes)]
        seen_row = Signal(row_shape)

        # The band's bounds, registered: the best fit is final before the scan starts.
        band_rows = Signal(range(-r, rows)), Signal(range(rows + r))
        band_cols = Signal(range(-r, cols)), Signal(range(cols + r))
        m.d.sync += [
            band_rows[0].eq(self.best_i - r), band_rows[1].eq(self.best_i + r),
            band_cols[0].eq(self.best_j - r), band_cols[1].eq(self.best_j + r),
        ]

        def outside(index, band):
            return (index < band[0]) | (index > band[1])

        fetched, fetched_final = delayed(seen, 1, 1, "fetched"), delayed(seen_final, 1, 1, "fetched_final")
        fetched_row_minimum = delayed(seen_row_minimum, 1, 1, "fetched_row_minimum")
        fetched_slot = delayed(seen_slot, seen_slot.shape(), 1, "fetched_slot")
        fetched_cols = [delayed(seen_col, seen_col.shape(), 1, f"fetched_col{lane}")
                        for lane, seen_col in enumerate(seen_cols)]
        fetched_row = delayed(seen_row, row_shape, 1, "fetched_row")
        fetched_minimum = delayed(self.minima_read.data, row_minimum_layout(p), 1, "fetched_minimum")
        fetched_words = delayed(self.slots_read.data, self.values_layout, 1, "fetched_words")

        key_shape = unsigned(p.value_bits + p.row_bits + p.col_bits)
        slot_row = Signal(row_shape)
        slot_in_band = Signal()
        with m.Switch(fetched_slot):
            for s in range(slots):
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
        candidate_ok, candidate_key = candidate_tree.root.valid, candidate_tree.root.key
        candidate_final = delayed(fetched & fetched_final, 1, candidate_tree.latency + 1, "candidate_final")

        runner_key = Signal(key_shape)
        runner_valid = Signal()
        with m.If(candidate_ok & (~runner_valid | (candidate_key < runner_key))):
            m.d.sync += [runner_key.eq(candidate_key), runner_valid.eq(1)]
        m.d.comb += [
            self.runner.valid.eq(runner_valid),
            self.runner.value.eq(runner_key[p.row_bits + p.col_bits:]),
            self.runner.i.eq(runner_key[p.col_bits:p.row_bits + p.col_bits]),
            self.runner.j.eq(runner_key[:p.col_bits]),
        ]

        with m.If(self.start):
            m.d.sync += [scanning.eq(1), step.eq(0), runner_valid.eq(0), slot_index.eq(0), slot_col.eq(0)]
        m.d.sync += seen.eq(scanning)
        with m.If(scanning):
            m.d.sync += [
                seen_final.eq(step == scan_end - 1),
                seen_row_minimum.eq(step < scan_rows_end),
                seen_row.eq(step),
                seen_slot.eq(slot_index),
                *(seen_col.eq(slot_col + lane) for lane, seen_col in enumerate(seen_cols)),
                step.eq(step + 1),
            ]
            with m.If(step >= scan_rows_end):
                with m.If(slot_col == (beats_per_row - 1) * lanes):
                    m.d.sync += [slot_col.eq(0), slot_index.eq(slot_index + 1)]
                with m.Else():
                    m.d.sync += slot_col.eq(slot_col + lanes)
            with m.If(step == scan_end - 1):
                m.d.sync += scanning.eq(0)
        done = Signal()
        with m.If(candidate_final):
            # The last word reaches the runner-up on this edge; it is final on the next.
            m.d.sync += done.eq(1)
        with m.If(self.taken):
            m.d.sync += done.eq(0)
        m.d.comb += self.done.eq(done)
        return m
