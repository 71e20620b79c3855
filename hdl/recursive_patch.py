"""The recursive core's patch: stored as it arrives, compacted at start to a list of its valid nodes."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from amaranth.hdl import Module, Mux, Signal, signed, unsigned
from amaranth.lib import data, memory, stream, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import ceil_log2

from lost.hdl.interface import CorrelatorParameters, checked_parameters
from lost.hdl.recursive_term import RecursiveShapes

__all__ = ["NodeCompaction", "node_layout"]


def node_layout(p: CorrelatorParameters) -> data.StructLayout:
    """A valid node: its map offset ``k * W + l`` from the placement's corner, and its centred depth C."""
    (_, W), (h, w) = p.map_shape, p.patch_shape
    return data.StructLayout({
        "offset": unsigned(max(((h - 1) * W + w - 1).bit_length(), 1)),
        "centred": RecursiveShapes.of(p).centred,
    })


@dataclass(frozen=True)
class _PassState:
    """The compaction passes' registers that the state machine sets: the results and the pass's position."""

    mean: Signal
    count: Signal
    patch_sum: Signal
    factor: Signal
    empty: Signal
    count_last: Signal
    prepare_index: Signal
    prepare_second: Signal
    prepare_offset: Signal
    prepare_col: Signal
    seen: Signal
    seen_second: Signal
    seen_offset: Signal
    append_index: Signal


class NodeCompaction(wiring.Component):
    """The patch memory, and the two passes at start that write the list of valid nodes.

    Patch words accepted since the last ``start`` fill nodes ``0, 1, ...`` (raster order). At start,
    the first pass counts the valid nodes (``n``) and sums their depths (``Ssum``); the second, with
    ``f`` known (``n`` with mean compensation, 1 without), appends each valid node with its map offset
    and its centred depth ``C = f * S - Ssum`` (``S`` without mean compensation) to the node list,
    through ``nodes_write``. A word read from the patch memory is registered, then counted or scaled
    (``f * S``, the multiplier between registers), then appended: the memory's output, the multiplier
    and the subtraction are on separate clocks.

    Latency: with ``start`` high in the cycle ending on edge 0, ``done`` is high in the cycle ending on
    edge ``2 * h * w + 3``, on which the last node is appended; ``empty`` and ``count_last`` are final
    from edge ``2 * h * w + 2``, ``mean`` and ``factor`` from the first pass's end.

    Parameters
    ----------
    parameters : CorrelatorParameters

    Members
    -------
    patch_in : ``In(stream.Signature(PatchWord(b)))``
        Ready while ``accept`` is high.
    accept : ``In(1)``
    start : ``In(1)``
        A start beat transfers; ``start_mode`` is its ``mean_compensation``.
    start_mode : ``In(1)``
    nodes_write : ``In(memory.WritePort.Signature(...))``
        The node list's write port (:func:`node_layout` words, ``n`` of them after the pass).
    mean, factor : ``Out(1)``, ``Out(range(h * w + 1))``
        The mode and ``f``.
    empty : ``Out(1)``
        No valid node: every term is zero.
    count_last : ``Out(range(h * w))``
        ``n - 1``, the last node's index.
    done : ``Out(1)``
    """

    def __init__(self, *, parameters: CorrelatorParameters):
        checked_parameters(parameters)
        self._parameters = p = parameters
        nodes = p.patch_shape[0] * p.patch_shape[1]
        self.node_layout = node_layout(p)
        super().__init__({
            "patch_in": In(stream.Signature(p.patch_word)),
            "accept": In(1),
            "start": In(1),
            "start_mode": In(1),
            "nodes_write": In(memory.WritePort.Signature(addr_width=ceil_log2(nodes), shape=self.node_layout)),
            "mean": Out(1),
            "factor": Out(range(nodes + 1)),
            "empty": Out(1),
            "count_last": Out(range(nodes)),
            "done": Out(1),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        patch_read = self._patch_memory(m)
        state = self._pass_state(m)
        self._pass(m, patch_read, state)
        self._control(m, state)
        return m

    def _patch_memory(self, m: Module) -> memory.ReadPort:
        """The patch memory, written by the accepted patch words in raster order; returns its read port."""
        p = self._parameters
        nodes_total = p.patch_shape[0] * p.patch_shape[1]
        m.submodules.patch = patch = memory.Memory(shape=p.patch_word, depth=nodes_total, init=[])
        patch_write, patch_read = patch.write_port(), patch.read_port()
        load_index = Signal(range(nodes_total))
        m.d.comb += [
            self.patch_in.ready.eq(self.accept),
            patch_write.addr.eq(load_index),
            patch_write.data.eq(self.patch_in.payload),
            patch_write.en.eq(self.patch_in.valid & self.patch_in.ready),
        ]
        with m.If(patch_write.en):
            m.d.sync += load_index.eq(Mux(load_index == nodes_total - 1, 0, load_index + 1))
        return patch_read

    def _pass_state(self, m: Module) -> _PassState:
        """The passes' results (the outputs' registers) and their position, which :meth:`_control` sets."""
        p = self._parameters
        (h, w) = p.patch_shape
        nodes_total = h * w
        offset_shape = self.node_layout["offset"].shape
        mean = Signal()                                   # latched from the start command
        count = Signal(range(nodes_total + 1))            # n, the valid nodes
        patch_sum = Signal(signed(p.widths.window_sum.bits))
        # f = n with mean compensation, 1 without; it scales map words and patch depths alike.
        # A register of its own, kept equal to Mux(mean, count, 1), so that the multipliers' inputs are
        # registers.
        factor = Signal(range(nodes_total + 1))
        # Registered once n is known, off the generator's path to the node memory's address.
        empty = Signal()
        count_last = Signal(range(nodes_total))  # n - 1
        m.d.comb += [self.mean.eq(mean), self.factor.eq(factor), self.empty.eq(empty), self.count_last.eq(count_last)]

        prepare_index = Signal(range(nodes_total))
        prepare_second = Signal()
        prepare_offset = Signal(offset_shape)
        prepare_col = Signal(range(w))
        seen, seen_second = Signal(), Signal()
        seen_offset = Signal(offset_shape)
        append_index = Signal(range(nodes_total))
        return _PassState(mean, count, patch_sum, factor, empty, count_last, prepare_index, prepare_second,
                          prepare_offset, prepare_col, seen, seen_second, seen_offset, append_index)

    def _pass(self, m: Module, patch_read: memory.ReadPort, state: _PassState) -> None:
        """The passes' pipeline: read, stage, count or scale, append.

        Two passes over the patch memory: read word k; one cycle later register it (``staged``); then
        count it and add it to Ssum (first pass), or register f * S (second pass, when n is known) and
        append the node with its centred depth f * S - Ssum a cycle after.
        """
        shapes = RecursiveShapes.of(self._parameters)
        offset_shape = self.node_layout["offset"].shape
        mean, count, patch_sum, factor = state.mean, state.count, state.patch_sum, state.factor
        m.d.comb += patch_read.addr.eq(state.prepare_index)
        word = patch_read.data
        staged, staged_second = Signal(), Signal()
        staged_depth = Signal.like(word.depth)
        staged_offset = Signal(offset_shape)
        m.d.sync += [
            staged.eq(state.seen & word.valid),
            staged_second.eq(state.seen_second),
            staged_depth.eq(word.depth),
            staged_offset.eq(state.seen_offset),
        ]
        with m.If(staged & ~staged_second):
            m.d.sync += [
                count.eq(count + 1),
                factor.eq(Mux(mean, count + 1, 1)),
                patch_sum.eq(patch_sum + staged_depth),
            ]
        scaled, scaled_offset = Signal(), Signal(offset_shape)
        scaled_depth = Signal(shapes.scaled)
        m.d.sync += [
            scaled.eq(staged & staged_second),
            scaled_depth.eq(factor * staged_depth),
            scaled_offset.eq(staged_offset),
        ]
        m.d.comb += [
            self.nodes_write.addr.eq(state.append_index),
            self.nodes_write.data.offset.eq(scaled_offset),
            self.nodes_write.data.centred.eq(scaled_depth - Mux(mean, patch_sum, 0)),
            self.nodes_write.en.eq(scaled),
        ]
        with m.If(scaled):
            m.d.sync += state.append_index.eq(state.append_index + 1)

    def _control(self, m: Module, s: _PassState) -> None:
        """The state machine: idle, the two passes over the patch, the last word's stages."""
        (_, W), (h, w) = self._parameters.map_shape, self._parameters.patch_shape
        nodes_total = h * w
        with m.FSM():
            with m.State("IDLE"):
                with m.If(self.start):
                    m.d.sync += [
                        s.mean.eq(self.start_mode),
                        s.count.eq(0),
                        s.factor.eq(~self.start_mode),
                        s.patch_sum.eq(0),
                        s.append_index.eq(0),
                        s.prepare_index.eq(0),
                        s.prepare_second.eq(0),
                        s.prepare_offset.eq(0),
                        s.prepare_col.eq(0),
                    ]
                    m.next = "PREPARE"
            with m.State("PREPARE"):
                m.d.sync += [s.seen.eq(1), s.seen_second.eq(s.prepare_second), s.seen_offset.eq(s.prepare_offset)]
                with m.If(s.prepare_index == nodes_total - 1):
                    m.d.sync += [s.prepare_index.eq(0), s.prepare_col.eq(0), s.prepare_offset.eq(0),
                                 s.prepare_second.eq(1)]
                    with m.If(s.prepare_second):
                        m.next = "PREPARE_LAST"
                with m.Else():
                    m.d.sync += s.prepare_index.eq(s.prepare_index + 1)
                    with m.If(s.prepare_col == w - 1):
                        m.d.sync += [s.prepare_col.eq(0), s.prepare_offset.eq(s.prepare_offset + W - w + 1)]
                    with m.Else():
                        m.d.sync += [s.prepare_col.eq(s.prepare_col + 1), s.prepare_offset.eq(s.prepare_offset + 1)]
            with m.State("PREPARE_LAST"):
                # The last patch word is seen on this cycle; staged on the next, scaled on the one after.
                m.d.sync += s.seen.eq(0)
                m.next = "PREPARE_STAGED"
            with m.State("PREPARE_STAGED"):
                # n is final from this cycle on (the last first-pass word was counted on the edge before).
                m.d.sync += [s.empty.eq(s.count == 0), s.count_last.eq(s.count - 1)]
                m.next = "PREPARE_SCALED"
            with m.State("PREPARE_SCALED"):
                # The last patch word is appended on this cycle's edge.
                m.d.comb += self.done.eq(1)
                m.next = "IDLE"
