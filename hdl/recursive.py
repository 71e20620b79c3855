"""The recursive-adder correlator: one absolute-difference unit and one accumulator, the fewest gates.

The principle of the 2002 correlator (Nygren, FOI-R--0764--SE, section 8), made exact: the placements
are taken one after the other, and for each the terms are formed one per clock by one arithmetic unit
and summed by one accumulator. The map memory is read once per term, through the
:class:`~lost.hdl.sequencer.MapSequencer`.

The arithmetic follows :mod:`lost.model.correlator`, rearranged so that nothing is computed per term
that can be computed once, and one datapath serves both modes::

    term(k) = f * M[i+k] - C[k] - f_sum(i, j)      for each valid patch node k
    C[k]    = f * S[k] - Ssum                      once per correlation, at start (the centred patch)
    f = n,  Ssum = sum_valid S,  f_sum = sum_valid M[i+.]   with mean compensation
    f = 1,  Ssum = 0,            f_sum = 0                  without

At start, two passes over the patch memory form ``n`` and ``Ssum``, then a compact list of the valid
nodes (map offset, ``C``); only valid nodes are visited afterwards, so a sparse mask costs fewer
cycles. The term unit forms ``f * M`` (one multiplication per term), one subtraction (``C + f_sum``
is summed beforehand), an absolute value and the accumulator, each on its own clock.

The window sum must be known before a placement's first term. Rather than reading the map twice, the
core reads each map word once and uses it twice, one placement apart: on each step it adds the word of
node ``k`` of placement ``q`` to the window sum and writes ``M`` into a small window memory
(``h * w`` words) at ``k``, whose read port returns, on the same edge, the word it overwrote: node ``k``
of placement ``q - 1``, whose window sum is complete by then. The term unit takes that word on the
next clock. So a placement costs ``n`` clocks in either mode, and one extra round of ``n`` steps after the
last placement empties the pipeline. The schedule is modelled exactly by
:func:`lost.model.cycles_recursive.schedule`.

The core joins its parts: :class:`~lost.hdl.recursive_patch.NodeCompaction` (the patch memory and
the node list), :class:`~lost.hdl.recursive_address.AddressGenerator` (a map read per valid node and
placement, and the flush round), the :class:`~lost.hdl.sequencer.MapSequencer` (the map reads as
streams), the window memory and the window sums (here, in ``_step_and_term``),
:class:`~lost.hdl.recursive_term.TermUnit` (the terms and the accumulator), the surface's positions and
the state machine (here), and :class:`~lost.hdl.reducer.BestFitReducer` (the best fit).

A patch without any valid node has nothing to correlate; the host refuses it
(:func:`lost.model.check_inputs`) before it reaches the core, which would give an all-zero surface (one
clock per placement) rather than hang.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from amaranth.hdl import Module, Mux, Signal, Value, signed
from amaranth.lib import memory, wiring
from amaranth.lib.wiring import In
from amaranth.utils import ceil_log2

from lost.hdl.interface import CorrelatorParameters, correlator_signature
from lost.hdl.recursive_address import AddressGenerator
from lost.hdl.recursive_patch import NodeCompaction
from lost.hdl.recursive_term import TermUnit
from lost.hdl.reducer import BestFitReducer
from lost.hdl.sequencer import MapSequencer

__all__ = ["RecursiveCore", "RecursiveCorrelator"]


@dataclass(frozen=True)
class _Generator:
    """The map reads' sequencer, and the generator's start that the control drives."""

    sequencer: MapSequencer
    start: Signal


def _parameters(map_shape, patch_shape, depth_bits, exclusion_radius) -> CorrelatorParameters:
    return CorrelatorParameters(map_shape=map_shape, patch_shape=patch_shape, depth_bits=depth_bits,
                                lanes=1, exclusion_radius=exclusion_radius)


def _map_read_signature(parameters: CorrelatorParameters) -> memory.ReadPort.Signature:
    (H, W) = parameters.map_shape
    return memory.ReadPort.Signature(addr_width=ceil_log2(H * W), shape=signed(parameters.depth_bits))


class RecursiveCore(wiring.Component):
    """The recursive-adder correlator without its map memory, which it reads through ``map_read``.

    Parameters
    ----------
    map_shape, patch_shape, depth_bits, exclusion_radius
        As :class:`RecursiveCorrelator`.

    Members
    -------
    patch_in, start, surface, best, busy
        As :func:`lost.hdl.interface.correlator_signature` (``surface`` has one lane).
    map_read : ``In(memory.ReadPort.Signature(addr_width=ceil_log2(H * W), shape=signed(depth_bits)))``
        A synchronous read port of the map memory, map word ``(r, c)`` at address ``r * W + c``.
    """

    def __init__(self, *, map_shape, patch_shape, depth_bits=16, exclusion_radius=1):
        self._parameters = parameters = _parameters(map_shape, patch_shape, depth_bits, exclusion_radius)
        members = correlator_signature(parameters)
        del members["map_in"]
        members["map_read"] = In(_map_read_signature(parameters))
        super().__init__(members)

    @property
    def parameters(self) -> CorrelatorParameters:
        return self._parameters

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        p = self._parameters
        busy = Signal()
        running = Signal()
        m.submodules.reducer = reducer = BestFitReducer(parameters=p)
        m.d.comb += [busy.eq(running | reducer.busy), self.busy.eq(busy)]
        start = self.start.valid & self.start.ready

        compaction, nodes_read = self._patch(m, busy, start)
        generator = self._generator(m, compaction, nodes_read)
        terms = self._step_and_term(m, generator.sequencer, compaction)
        out_i, out_j, surface_taken = self._surface(m, terms, running)

        # The reducer watches the surface's transfers and answers on ``best``.
        m.d.comb += [
            reducer.surface.valid.eq(surface_taken),
            reducer.surface.payload.eq(self.surface.payload),
        ]
        wiring.connect(m, reducer.best, wiring.flipped(self.best))

        self._control(m, start, busy, running, compaction, generator, (out_i, out_j))
        return m

    def _patch(self, m: Module, busy: Signal, start: Value) -> tuple[NodeCompaction, memory.ReadPort]:
        """The patch: loaded while idle, compacted to its valid nodes at start (``NodeCompaction``)."""
        p = self._parameters
        m.submodules.compaction = compaction = NodeCompaction(parameters=p)
        wiring.connect(m, wiring.flipped(self.patch_in), compaction.patch_in)
        m.d.comb += [compaction.accept.eq(~busy), compaction.start.eq(start),
                     compaction.start_mode.eq(self.start.payload.mean_compensation)]
        m.submodules.nodes = nodes = memory.Memory(shape=compaction.node_layout, depth=p.patch_shape[0] * p.patch_shape[1], init=[])
        nodes_write = nodes.write_port()
        wiring.connect(m, compaction.nodes_write, nodes_write)
        # Transparent: the first node may be written on the very edge the generator first reads it.
        nodes_read = nodes.read_port(transparent_for=(nodes_write,))
        return compaction, nodes_read

    def _generator(self, m: Module, compaction: NodeCompaction, nodes_read: memory.ReadPort) -> _Generator:
        """The address generator (``AddressGenerator``) and the ``MapSequencer`` its requests read the map through."""
        p = self._parameters
        m.submodules.generator = generator = AddressGenerator(parameters=p)
        m.submodules.sequencer = sequencer = MapSequencer(
            addr_width=_map_read_signature(p).addr_width, shape=signed(p.depth_bits), tag_shape=generator.tag_layout)
        wiring.connect(m, wiring.flipped(self.map_read), sequencer.read)
        wiring.connect(m, generator.request, sequencer.request)
        wiring.connect(m, generator.nodes_read, nodes_read)
        m.d.comb += [generator.count_last.eq(compaction.count_last), generator.empty.eq(compaction.empty)]
        return _Generator(sequencer=sequencer, start=generator.start)

    def _step_and_term(self, m: Module, sequencer: MapSequencer, compaction: NodeCompaction) -> TermUnit:
        """Each step sums the window of placement q and keeps its words; the term unit takes placement q-1's."""
        p = self._parameters
        h, w = p.patch_shape
        widths = p.widths
        m.submodules.window = window = memory.Memory(shape=signed(p.depth_bits), depth=h * w, init=[])
        window_write = window.write_port()
        window_read = window.read_port()  # not transparent: it reads the word being overwritten
        response = sequencer.response
        tag = response.payload.tag
        map_word = response.payload.data
        step = response.valid & response.ready

        window_sum = Signal(signed(widths.window_sum.bits))
        next_window_sum = Signal(signed(widths.window_sum.bits))        # sum_valid M of placement q
        previous_window_sum = Signal(signed(widths.window_sum.bits))    # that of placement q-1
        window_sum_new = Mux(tag.first, 0, window_sum) + map_word
        m.d.comb += [
            window_write.addr.eq(tag.index),
            window_write.data.eq(map_word),
            window_write.en.eq(step & tag.current),
            window_read.addr.eq(tag.index),
            window_read.en.eq(step),  # held while the term stage waits
        ]
        with m.If(step & tag.current):
            m.d.sync += window_sum.eq(window_sum_new)
            with m.If(tag.last):
                m.d.sync += next_window_sum.eq(window_sum_new)
        with m.If(step & tag.previous & tag.first):
            m.d.sync += previous_window_sum.eq(next_window_sum)

        # The term: one absolute difference and one accumulator. What it subtracts besides the window
        # word, C + Msum of placement q-1, is summed on the step itself; the window word follows from
        # the memory read on the same edge.
        m.submodules.terms = terms = TermUnit(parameters=p)
        # On the step of a placement's first node, Msum of the previous placement moves from
        # ``next_window_sum`` to ``previous_window_sum`` on this very edge.
        previous_sum = Mux(tag.first, next_window_sum, previous_window_sum)
        m.d.comb += [
            response.ready.eq(terms.advance),
            terms.term.valid.eq(step & tag.previous),
            terms.term.first.eq(tag.first),
            terms.term.last.eq(tag.last),
            terms.term.offset.eq(tag.centred + Mux(compaction.mean, previous_sum, 0)),
            terms.word.eq(window_read.data),
            terms.factor.eq(compaction.factor),
            terms.empty.eq(compaction.empty),
        ]
        return terms

    def _surface(self, m: Module, terms: TermUnit, running: Signal) -> tuple[Signal, Signal, Value]:
        """The surface: the term unit's values placed in raster order; the last one ends the run."""
        rows, cols = self._parameters.surface_shape
        out_i, out_j = Signal(range(rows)), Signal(range(cols))
        surface_taken = self.surface.valid & self.surface.ready
        surface_last = (out_i == rows - 1) & (out_j == cols - 1)
        m.d.comb += [
            self.surface.valid.eq(terms.value.valid),
            terms.value.ready.eq(self.surface.ready),
            self.surface.payload.values[0].eq(terms.value.payload),
            self.surface.payload.count.eq(1),
            self.surface.payload.i.eq(out_i),
            self.surface.payload.j.eq(out_j),
            self.surface.payload.last.eq(surface_last),
        ]
        with m.If(surface_taken):
            with m.If(surface_last):
                m.d.sync += running.eq(0)
            with m.Elif(out_j == cols - 1):
                m.d.sync += [out_j.eq(0), out_i.eq(out_i + 1)]
            with m.Else():
                m.d.sync += out_j.eq(out_j + 1)
        return out_i, out_j, surface_taken

    def _control(self, m: Module, start: Value, busy: Signal, running: Signal, compaction: NodeCompaction,
                 generator: _Generator, out: tuple[Signal, Signal]) -> None:
        """IDLE -> PREPARE (the compaction) -> RUN until the last surface beat."""
        g = generator
        m.d.comb += self.start.ready.eq(~busy)
        with m.FSM():
            with m.State("IDLE"):
                with m.If(start):
                    m.d.sync += [running.eq(1), out[0].eq(0), out[1].eq(0)]
                    m.next = "PREPARE"
            with m.State("PREPARE"):
                # The last valid node is appended on this cycle's edge; the generator starts on it.
                m.d.comb += g.start.eq(compaction.done)
                with m.If(compaction.done):
                    m.next = "RUN"
            with m.State("RUN"):
                with m.If(~running):
                    m.next = "IDLE"


class RecursiveCorrelator(wiring.Component):
    """The recursive-adder correlator with its map memory: the contract's ports.

    Parameters
    ----------
    map_shape : (int, int)
        ``(H, W)``, the map the core stores.
    patch_shape : (int, int)
        ``(h, w)``, the patch.
    depth_bits : int
        Width of a depth word.
    exclusion_radius : int
        Radius around the best fit that the runner-up is searched outside of.

    Members
    -------
    map_in, patch_in, start, surface, best, busy
        As :func:`lost.hdl.interface.correlator_signature`, with one lane.

    Raises
    ------
    ValueError
        See :class:`lost.hdl.interface.CorrelatorParameters`.
    """

    def __init__(self, *, map_shape, patch_shape, depth_bits=16, exclusion_radius=1):
        self._parameters = _parameters(map_shape, patch_shape, depth_bits, exclusion_radius)
        super().__init__(correlator_signature(self._parameters))

    @property
    def parameters(self) -> CorrelatorParameters:
        return self._parameters

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        p = self._parameters
        (H, W) = p.map_shape
        m.submodules.core = core = RecursiveCore(
            map_shape=p.map_shape, patch_shape=p.patch_shape, depth_bits=p.depth_bits,
            exclusion_radius=p.exclusion_radius)
        m.submodules.map = map_memory = memory.Memory(shape=signed(p.depth_bits), depth=H * W, init=[])
        map_write = map_memory.write_port()
        wiring.connect(m, core.map_read, map_memory.read_port())

        load_address = Signal(range(H * W))
        m.d.comb += [
            self.map_in.ready.eq(~core.busy),
            map_write.addr.eq(load_address),
            map_write.data.eq(self.map_in.payload),
            map_write.en.eq(self.map_in.valid & self.map_in.ready),
        ]
        with m.If(map_write.en):
            m.d.sync += load_address.eq(Mux(load_address == H * W - 1, 0, load_address + 1))

        wiring.connect(m, wiring.flipped(self.patch_in), core.patch_in)
        wiring.connect(m, wiring.flipped(self.start), core.start)
        wiring.connect(m, core.surface, wiring.flipped(self.surface))
        wiring.connect(m, core.best, wiring.flipped(self.best))
        m.d.comb += self.busy.eq(core.busy)
        return m
