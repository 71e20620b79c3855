"""The window correlator's patch: stored as it arrives, prepared once per correlation at start.

The lanes need, for a whole correlation, the patch's valid bits, its lifted depths ``2**b - S``, the
mode, ``f`` (``n`` with mean compensation, 1 without) and the dividend's bias ``f * 2**b - Ssum``
(``-Ssum`` without). :class:`PatchPreparation` keeps the patch and forms them in one pass over it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from amaranth.hdl import Cat, Module, Mux, Signal
from amaranth.lib import data, memory, stream, wiring
from amaranth.lib.wiring import In, Out

from lost.hdl.blocks import Replicas, index_range
from lost.hdl.interface import CorrelatorParameters, checked_parameters
from lost.hdl.window_lane import LaneArithmetic

#: Lifted-patch registers enabled by one copy of the pass's enable (a patch row of Nygren's 10 x 10).
LIFTING_COPY_NODES = 10

__all__ = ["PatchPreparation"]


@dataclass(frozen=True)
class _Held:
    """The registers :class:`PatchPreparation` holds for the lanes (its outputs) and the pass's sums."""

    patch_valid: Signal
    lifted_patch: Signal
    mean_compensation: Signal
    valid_count: Signal
    patch_sum: Signal
    factor: Signal
    dividend_bias: Signal


class PatchPreparation(wiring.Component):
    """The patch memory, and the pass at start that forms ``n``, ``Ssum`` and the lifted depths.

    Patch words accepted since the last ``start`` (or reset) fill nodes ``0, 1, ...`` (raster order);
    like the map, the patch persists through a reset until reloaded: its depths live in a small memory
    read in place by the pass (so a reset mid-pass leaves it intact), its valid bits, which every lane
    needs at once, in a reset-less register.

    Latency: with ``start`` high in the cycle ending on edge 0, ``done`` is high in the cycle ending
    on edge ``h * w + 3`` (the pass takes a node per clock, after the memory's read register and one
    after it: a block RAM's output is slow), when ``dividend_bias`` loads; every output holds from
    edge ``h * w + 3`` until the next ``start``. ``factor``, ``lifted_patch`` and ``patch_valid`` are
    final an edge earlier. Each of ``lane_patch_valid`` equals ``patch_valid`` on every cycle (each of
    ``lane_patch_invalid``, ``~patch_valid``).

    Parameters
    ----------
    parameters : CorrelatorParameters
    lane_resets : bool
        The lanes' copies as the window core's lanes use them: inverted (``lane_patch_invalid``) and
        each loaded on its own enable (``lane_accept``).

    Members
    -------
    patch_in : ``In(stream.Signature(PatchWord(b)))``
        Ready while ``accept`` is high.
    accept : ``In(1)``
        The core takes patch words (it is idle).
    idle : ``In(1)``
        The core runs no correlation: the pass's sums are cleared.
    start : ``In(1)``
        A start beat transfers (it must be while ``idle``); ``start_mode`` is its ``mean_compensation``.
    start_mode : ``In(1)``
    done : ``Out(1)``
        The pass's last cycle.
    patch_valid, lifted_patch, mean_compensation, factor, dividend_bias : ``Out(...)``
        As the :class:`~lost.hdl.window_lane.WindowLane`'s ports of those names.
    lane_patch_valid : ``Out(ArrayLayout(h * w, lanes))``
        A copy of ``patch_valid`` for each lane, a register of its own (the same value on every cycle).
        Not with ``lane_resets=True``.
    lane_patch_invalid : ``Out(ArrayLayout(h * w, lanes))``
        Only with ``lane_resets=True``, instead of ``lane_patch_valid``: for each lane, a register of
        its own equal to ``~patch_valid`` on every cycle (the invalid bits are the resets of a lane's
        per-node registers, so a lane reads them with no inverter, one LUT4 a node otherwise).
    lane_accept : ``In(ArrayLayout(1, lanes))``
        Only with ``lane_resets=True``: for each lane's copy a copy of ``accept`` (the caller's
        registers, each equal to ``accept`` on every cycle), so that each lane's copy has a load
        enable of its own: one enable for all of them spans the chip.
    """

    def __init__(self, *, parameters: CorrelatorParameters, lane_resets: bool = False):
        checked_parameters(parameters)
        if not isinstance(lane_resets, bool):
            raise ValueError(f"lane_resets must be a bool, got {lane_resets!r}")
        self._parameters = p = parameters
        self._lane_resets = lane_resets
        self._arithmetic = a = LaneArithmetic.of(p)
        nodes = p.patch_shape[0] * p.patch_shape[1]
        super().__init__({
            "patch_in": In(stream.Signature(p.patch_word)),
            "accept": In(1),
            "idle": In(1),
            "start": In(1),
            "start_mode": In(1),
            "done": Out(1),
            "patch_valid": Out(nodes),
            ("lane_patch_invalid" if lane_resets else "lane_patch_valid"): Out(data.ArrayLayout(nodes, p.lanes)),
            "lifted_patch": Out(data.ArrayLayout(a.lifted, nodes)),
            "mean_compensation": Out(1),
            "factor": Out(a.count),
            "dividend_bias": Out(a.bias),
            **({"lane_accept": In(data.ArrayLayout(1, p.lanes))} if lane_resets else {}),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        a, nodes = self._arithmetic, self._parameters.patch_shape[0] * self._parameters.patch_shape[1]
        m.submodules.patch_memory = patch_memory = memory.Memory(shape=a.depth, depth=nodes, init=[])
        patch_write = patch_memory.write_port()
        patch_read = patch_memory.read_port()
        held = self._held(m)
        patch_pointer = self._load(m, patch_write, held.patch_valid)
        lifting_next, prepare_step, head_valid = self._pass(m, patch_read, held)
        self._control(m, held, patch_pointer, lifting_next, prepare_step, head_valid)
        return m

    def _held(self, m: Module) -> _Held:
        """The registers the lanes read through a correlation (the outputs) and the pass's sums."""
        a, nodes = self._arithmetic, self._parameters.patch_shape[0] * self._parameters.patch_shape[1]
        patch_valid = Signal(nodes, reset_less=True)
        lifted_patch = Signal(data.ArrayLayout(a.lifted, nodes), reset_less=True)
        mean_compensation = Signal()
        valid_count = Signal(a.count)
        patch_sum = Signal(a.window_sum)
        factor = Signal(a.count)
        dividend_bias = Signal(a.bias)
        m.d.comb += [
            self.patch_valid.eq(patch_valid),
            self.lifted_patch.eq(lifted_patch),
            self.mean_compensation.eq(mean_compensation),
            self.factor.eq(factor),
            self.dividend_bias.eq(dividend_bias),
        ]
        return _Held(patch_valid, lifted_patch, mean_compensation, valid_count, patch_sum, factor, dividend_bias)

    def _load(self, m: Module, patch_write: memory.WritePort, patch_valid: Signal) -> Signal:
        """Patch words since the last start (or reset) fill nodes 0, 1, ...; the valid bits shift in.

        Returns the write pointer (the state machine clears it at start).
        """
        p = self._parameters
        nodes = p.patch_shape[0] * p.patch_shape[1]
        patch_pointer = Signal(index_range(nodes))
        loading = self.patch_in.valid & self.patch_in.ready
        # Each lane takes a copy of the valid bits, loaded with them from the same shifted value so that every
        # copy equals them (reset-less, as they are): a valid bit resets 33 of a lane's registers, and one
        # register driving them in every lane is a chip-wide net (the critical path of c984e45's 4-lane build:
        # 10.8 ns of routing to the last lane's quotient copy). Loaded only on a patch word, the copies need no LUT.
        # Named ``*_replica`` so that the synthesis flow keeps them apart.
        if self._lane_resets:
            lane_copies = [Signal(nodes, name=f"lane{q}_patch_invalid_replica", init=(1 << nodes) - 1, reset_less=True)
                           for q in range(p.lanes)]
            m.d.comb += [self.lane_patch_invalid[q].eq(copy) for q, copy in enumerate(lane_copies)]
        else:
            lane_copies = [Signal(nodes, name=f"lane{q}_patch_valid_replica", reset_less=True) for q in range(p.lanes)]
            m.d.comb += [self.lane_patch_valid[q].eq(copy) for q, copy in enumerate(lane_copies)]
        m.d.comb += [
            self.patch_in.ready.eq(self.accept),
            patch_write.addr.eq(patch_pointer),
            patch_write.data.eq(self.patch_in.payload.depth),
            patch_write.en.eq(loading),
        ]
        shifted = Cat(patch_valid[1:], self.patch_in.payload.valid)
        shared_enable = [] if self._lane_resets else lane_copies
        with m.If(loading):
            m.d.sync += patch_pointer.eq(Mux(patch_pointer == nodes - 1, 0, patch_pointer + 1))
            m.d.sync += [patch_valid.eq(shifted), *(copy.eq(shifted) for copy in shared_enable)]
        if self._lane_resets:
            # Each copy shifts itself (it is ~patch_valid), so only the incoming bit reaches every lane.
            for q, copy in enumerate(lane_copies):
                with m.If(self.patch_in.valid & self.lane_accept[q]):
                    m.d.sync += copy.eq(Cat(copy[1:], ~self.patch_in.payload.valid))
        return patch_pointer

    def _pass(self, m: Module, patch_read: memory.ReadPort, held: _Held) -> tuple[Signal, Signal, Signal]:
        """The pass: each node's depth and valid bit read in place, then n, Ssum and the lifted depths.

        The memory's read register and one after it keep its paths short. Returns ``lifting``'s next
        value (set by the state machine), the pass's step and the node taken's valid bit.
        """
        a, nodes = self._arithmetic, self._parameters.patch_shape[0] * self._parameters.patch_shape[1]
        idle, lifted_patch, valid_count, patch_sum = self.idle, held.lifted_patch, held.valid_count, held.patch_sum
        prepare_step = Signal(range(nodes + 2))
        lifting = Signal()  # the pass takes a node: n, Ssum and lifted_patch (cycles 3 .. hw + 2)
        lifting_next = Signal()  # the value ``lifting`` takes on the next edge (set by the state machine)
        m.d.comb += lifting_next.eq(lifting)
        m.d.sync += lifting.eq(lifting_next)
        # The lifted patch's registers take a copy of ``lifting`` per row of the patch, loaded from the same next
        # value so that every copy equals ``lifting``: one register enabling all of them is a chip-wide net (the
        # critical path of f490ab4's 4-lane build: 17.3 ns of routing to 1,700 clock enables).
        copies = -(-nodes // LIFTING_COPY_NODES)
        m.submodules.lifting_copies = lifting_copies = Replicas(1, copies)
        m.d.comb += lifting_copies.i.eq(lifting_next)
        node = Signal(index_range(nodes))
        with m.If(idle | (node == nodes - 1)):
            m.d.sync += node.eq(0)
        with m.Else():
            m.d.sync += node.eq(node + 1)
        head_read = Signal(a.depth)
        head_depth = Signal(a.depth)
        head_valid_read = Signal()
        head_valid = Signal()
        m.d.comb += [patch_read.addr.eq(node), head_read.eq(patch_read.data)]
        m.d.sync += [
            head_valid_read.eq(held.patch_valid.bit_select(node, 1)),
            head_depth.eq(head_read),
            head_valid.eq(head_valid_read),
        ]
        # Outside the state machine, so that a register alone enables the pass's registers.
        for x in range(nodes):
            with m.If(lifting_copies.o[x // LIFTING_COPY_NODES]):
                m.d.sync += lifted_patch[x].eq(lifted_patch[x + 1] if x < nodes - 1 else a.lift - head_depth)
        with m.If(lifting):
            m.d.sync += [
                valid_count.eq(valid_count + head_valid),
                patch_sum.eq(patch_sum + Mux(head_valid, head_depth, 0)),
            ]
        with m.If(idle):
            m.d.sync += [valid_count.eq(0), patch_sum.eq(0), prepare_step.eq(0)]
        return lifting_next, prepare_step, head_valid

    def _control(self, m: Module, held: _Held, patch_pointer: Signal, lifting_next: Signal, prepare_step: Signal,
                 head_valid: Signal) -> None:
        """The state machine: idle, the pass (``COUNT``), then ``f`` and the dividend's bias."""
        nodes, b = self._parameters.patch_shape[0] * self._parameters.patch_shape[1], self._parameters.depth_bits
        mean_compensation, factor = held.mean_compensation, held.factor
        with m.FSM():
            with m.State("IDLE"):
                with m.If(self.start):
                    m.d.sync += [mean_compensation.eq(self.start_mode), patch_pointer.eq(0)]
                    m.next = "COUNT"
            with m.State("COUNT"):
                # n, sum_valid S and the lifted depths, from node k - 2 on cycle k = 2 .. hw + 1.
                m.d.sync += prepare_step.eq(prepare_step + 1)
                with m.If(prepare_step == 1):
                    m.d.comb += lifting_next.eq(1)
                with m.If(prepare_step == nodes + 1):
                    m.d.comb += lifting_next.eq(0)
                    m.d.sync += factor.eq(Mux(mean_compensation, held.valid_count + head_valid, 1))
                    m.next = "BIAS"
            with m.State("BIAS"):
                m.d.comb += self.done.eq(1)
                m.d.sync += held.dividend_bias.eq(Mux(mean_compensation, factor << b, 0) - held.patch_sum)
                m.next = "IDLE"
