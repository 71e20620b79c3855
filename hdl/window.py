"""The shift-register / window correlator: every lane produces one placement per clock.

Nygren's shift-register principle (FOI-R--0764--SE, section 8.2) made exact and streaming: the map is
read once per correlation, one memory row of ``L`` words per clock in raster order; ``h - 1`` line
buffers turn that stream into columns of ``h`` words; a window register of columns holds every
``h x w`` window that the ``L`` lanes need; each lane then forms its ``h * w`` terms and their sum,
with a register after every adder level.

The arithmetic is :mod:`lost.model.correlator`'s, rearranged so that the per-node work is a pair of
``b + 1``-bit operations (``b`` depth bits), not an ``n``-scaled one. With ``d = M - S`` at the valid
nodes, ``E = sum_valid d`` (the window sum less ``Ssum = sum_valid S``) and ``t = floor(E / n)``, a
term of mean compensation ``n * d - E`` is positive exactly when ``d > t``, so::

    V = sum |n * d - E| = 2 * (n * P - E * K)       P = sum of d over d > t,  K = their count

and without mean compensation (``t = 0``) ``V = sum |d| = 2 * P - E``. Lifted by ``2**b``, every
quantity is unsigned: ``d' = M + (2**b - S)`` and ``q = t + 2**b = floor(N / f)`` with the dividend
``N = E + f * 2**b`` lie in ``[1, 2**(b+1) - 1]``, ``d > t`` is ``d' > q``, and with ``P'`` the sum of
the selected ``d'``::

    V = 2 * (f * P' - K * N) - correction      f = n, correction = 0    with mean compensation
                                               f = 1, N = 2**b,         without
                                               correction = E

``2**b - S`` is formed once per correlation, at start, with ``n``, ``Ssum`` and the dividend's bias
``f * 2**b - Ssum``. The window sum runs over the valid nodes only, so with a mask each column offset
has its own column sum and a sliding accumulator does not apply; per lane it costs ``h * w - 1``
adders either as masked column sums plus a row sum or, as here, as one balanced tree. The tree starts
on the columns as soon as they enter the window register, from a register of the masked depths (an
invalid node's held at zero by its synchronous reset); the dividend follows, then the quotient, an exact
reciprocal product (:func:`~lost.hdl.reciprocal.reciprocal_quotient`), over
:data:`~lost.model.cycles_window.QUOTIENT_STAGES` stages; the terms are formed
from the same columns, which have moved down the register by then, so nothing needs a delay line.
A node's selected ``d'`` is a register's synchronous reset, one LUT per node; the two products per
lane are multipliers, formed modulo ``2**accumulator_bits`` (``V`` is below it, so exactly). Each lane
has registers of its own for the mode and ``f`` (named ``*_replica``, which the synthesis flow keeps
apart), and copies of its quotient near the comparators.

Only the step-synchronous stages (the step register, the line buffers, the window register, the masked
depths, the window-sum tree, the dividend and the quotient stages) hold still between steps; a step
is a map word or, at the end, one of a fixed number of flush steps. Their one enable is a register,
``advance``, set on the edge a step is issued. The term stages (``d'``, the selected ``d'`` and their
count, the two sum trees, the partial products, their sums, the value) run on every clock with a valid bit beside them:
between steps they recompute the last placement, marked stale. Steps are issued against credits for
the output queue, one per beat it holds, so a beat always finds room and ``surface.ready`` stalls
nothing but the issue of further steps. The cycles are modelled exactly by
:mod:`lost.model.cycles_window`, whose :func:`~lost.model.cycles_window.window_timing` gives the
pipeline its constants.

The core is made of components, each with its latency in its docstring and a test of its own against
a NumPy model (``tests/hdl/test_window_parts.py``, ``tests/hdl/test_window_steps.py``):

* :class:`~lost.hdl.window_patch.PatchPreparation`: the patch memory and the pass at start;
* :class:`~lost.hdl.window_steps.StepIssue`: the steps, each issued against a credit (the map read
  requests, a stream), and the step enable ``advance``;
* :class:`~lost.hdl.sequencer.MapSequencer`: the map reads (a stream of requests and words);
* :class:`~lost.hdl.window_steps.BeatMetadata`: the group each step reads and the beat it completes,
  carried beside the step-synchronous and term stages to the output queue;
* :class:`~lost.hdl.window_columns.StepWindow`: the step register, line buffers and window register;
* :class:`~lost.hdl.window_lane.WindowLane`, one per lane: the threshold terms (masked depths,
  window sum, divider, selected differences, their sums, the products, the value);
* :class:`~lost.hdl.window_queue.CreditQueue`: the output queue and the credits for issuing steps;
* :class:`~lost.hdl.reducer.BestFitReducer`: the best fit and runner-up.

What stays here is their wiring, the acceptance of a start and the patch words (registers formed from
the next state), the register that clears the queue and the steps between correlations, and the state
machine (idle, the patch pass, the run). The stages are named by
:class:`~lost.hdl.window_lane.PipelineStages`. The beat metadata, the lane and the window follow the
step enable rather than a stream's handshake (their ports are step-synchronous), as does the step issue
beside its stream of map requests.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from amaranth.hdl import Module, Mux, Signal, Value, signed
from amaranth.lib import data, memory, wiring
from amaranth.lib.wiring import In
from amaranth.utils import ceil_log2

from lost.hdl.blocks import ProductBlock, RegisteredProduct, Replicas, index_range
from lost.hdl.interface import CorrelatorParameters, correlator_signature
from lost.hdl.reducer import BestFitReducer
from lost.hdl.sequencer import MapSequencer
from lost.hdl.window_columns import StepWindow
from lost.hdl.window_lane import PipelineStages, WindowLane
from lost.hdl.window_patch import PatchPreparation
from lost.hdl.window_queue import CreditQueue
from lost.hdl.window_steps import BeatMetadata, StepIssue
from lost.model.cycles_window import WindowTiming, window_timing

__all__ = ["PipelineStages", "WindowCore", "WindowCorrelator"]


#: How a high-fan-out enable reaches its loads: ``(module, enable) -> the value the loads see``.
EnableBuffer = Callable[[Module, Value], Value]


def _checked_choice(name: str, value: Any, signature: str, *, optional: bool = False) -> Any:
    """A builder's device choice (``enable_buffer``, ``product``) if it is a function, or ``None`` where
    ``optional``; else a ``ValueError`` naming it and what it must be."""
    if (optional and value is None) or callable(value):
        return value
    raise ValueError(f"{name} must be {'None or ' if optional else ''}a function {signature}, got {value!r}")


class WindowCore(wiring.Component):
    """The window correlator without its map memory, which it reads through ``map_read``.

    Parameters
    ----------
    map_shape, patch_shape, depth_bits, lanes, exclusion_radius, enable_buffer, product
        See :class:`WindowCorrelator`.

    Members
    -------
    patch_in, start, surface, best, busy
        As in :func:`lost.hdl.interface.correlator_signature`.
    map_read : ``In(memory.ReadPort.Signature(addr_width, shape=map_word))``
        A synchronous read port of the map memory: ``H * ceil(W / L)`` rows of ``L`` words, map row
        ``r`` at rows ``r * ceil(W / L) ...``, word ``c`` of it in lane ``c % L`` of row ``c // L``.
        Read through a :class:`~lost.hdl.sequencer.MapSequencer`, each row once per correlation.

    Attributes
    ----------
    map_word : ArrayLayout
        One memory row: ``L`` signed depth words.
    map_depth : int
        Rows of the map memory.
    timing : WindowTiming
        The pipeline's constants; the cycle of every beat is :func:`lost.model.cycles_window.schedule`.

    A patch without a valid node (which :func:`lost.model.check_inputs` refuses on the host) gives
    an all-zero surface.
    """

    def __init__(self, *, map_shape, patch_shape, depth_bits: int = 16, lanes: int = 1, exclusion_radius: int = 1,
                 enable_buffer: EnableBuffer | None = None, product: ProductBlock = RegisteredProduct):
        self._enable_buffer = _checked_choice("enable_buffer", enable_buffer, "(module, enable) -> Value", optional=True)
        self._product = _checked_choice("product", product, "(a_bits, b_bits) -> a RegisteredProduct's like")
        self._parameters = CorrelatorParameters(
            map_shape=map_shape, patch_shape=patch_shape, depth_bits=depth_bits, lanes=lanes,
            exclusion_radius=exclusion_radius)
        self._timing = window_timing(self._parameters.map_shape, self._parameters.patch_shape, lanes)
        H = self._parameters.map_shape[0]
        self.map_word = data.ArrayLayout(signed(depth_bits), lanes)
        self.map_depth = H * self._timing.groups
        ports = correlator_signature(self._parameters)
        del ports["map_in"]
        ports["map_read"] = In(memory.ReadPort.Signature(addr_width=ceil_log2(self.map_depth), shape=self.map_word))
        super().__init__(ports)

    @property
    def parameters(self) -> CorrelatorParameters:
        return self._parameters

    @property
    def timing(self) -> WindowTiming:
        return self._timing

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        stages = PipelineStages.of(self._timing)

        idle = Signal()
        idle_next = Signal()  # the value ``idle`` takes on the next edge (set by the state machine)
        m.submodules.reducer = reducer = BestFitReducer(parameters=self._parameters)
        ready_for_more, lane_ready = self._acceptance(m, reducer, idle_next)
        m.d.comb += [self.start.ready.eq(ready_for_more), self.busy.eq(~ready_for_more)]
        start = self.start.valid & self.start.ready

        patch = self._patch(m, ready_for_more, lane_ready, idle, start)
        sequencer, output_queue, steps = self._step_issue(m)
        # The builder's ``enable_buffer`` carries the step enable, a register, to its loads.
        advance = steps.advance if self._enable_buffer is None else self._enable_buffer(m, steps.advance)
        # The run's counters are cleared while idle (and on the pass's first cycle) by a register of their
        # own, so that the start beat's condition reaches only the pass's few registers.
        clearing = Signal(init=1)
        m.d.sync += clearing.eq(idle)
        m.submodules.beat_metadata = beats = BeatMetadata(parameters=self._parameters)
        m.d.comb += [beats.advance.eq(advance), beats.clear.eq(clearing)]
        window, sums_port = self._window(m, stages, advance, sequencer, beats, steps.step_is_word)
        lane_values = self._lanes(m, patch, window, sums_port, advance)
        self._output(m, output_queue, beats, lane_values)

        # The reducer watches the surface's transfers (registering each before any logic, so the
        # queue's read stays out of its paths) and answers on ``best``.
        m.d.comb += [
            reducer.surface.valid.eq(self.surface.valid & self.surface.ready),
            reducer.surface.payload.eq(self.surface.payload),
        ]
        wiring.connect(m, reducer.best, wiring.flipped(self.best))

        self._control(m, idle, idle_next, start, clearing, patch, steps, output_queue)
        return m

    def _acceptance(self, m: Module, reducer: BestFitReducer, idle_next: Value) -> tuple[Signal, Value]:
        """Whether the core takes a start or patch words (``idle & ~reducer.busy``), as registers.

        Formed from both flags' next values, so it equals ``idle & ~reducer.busy`` on every cycle: the
        patch words' load enable then starts at a register, not at the state register's decode and the
        reducer's flag (the critical path of d7d03eb's 4-lane build: 13.5 ns from ``fsm_state`` to the
        lanes' copies of the valid bits). Each lane's copy of the valid bits takes its own copy of it.
        The reducer's ``busy`` is set by a last surface beat's arrival and cleared by the best beat's
        transfer, which wins (:class:`~lost.hdl.reducer.BestFitReducer`).

        Returns the register and the lanes' copies of it.
        """
        best_taken = reducer.best.valid & reducer.best.ready
        last_arrives = reducer.surface.valid & reducer.surface.payload.last
        busy_next = ~best_taken & (last_arrives | reducer.busy)
        ready_next = idle_next & ~busy_next
        accepting = Signal(init=1)  # reset: idle and not busy
        m.d.sync += accepting.eq(ready_next)
        m.submodules.accepting_copies = copies = Replicas(1, self._parameters.lanes, init=1)
        m.d.comb += copies.i.eq(ready_next)
        return accepting, copies.o

    def _patch(self, m: Module, ready_for_more: Value, lane_ready: Value, idle: Signal,
               start: Value) -> PatchPreparation:
        """The patch, its count and sum, and its lifted depths ``2**b - S`` (formed at start)."""
        m.submodules.patch = patch = PatchPreparation(parameters=self._parameters, lane_resets=True)
        wiring.connect(m, wiring.flipped(self.patch_in), patch.patch_in)
        m.d.comb += [
            patch.accept.eq(ready_for_more),
            patch.lane_accept.eq(lane_ready),
            patch.idle.eq(idle),
            patch.start.eq(start),
            patch.start_mode.eq(self.start.payload.mean_compensation),
        ]
        return patch

    def _step_issue(self, m: Module) -> tuple[MapSequencer, CreditQueue, StepIssue]:
        """The map reads, the output queue and the steps, one issued per credit of the queue."""
        p, t = self._parameters, self._timing
        m.submodules.sequencer = sequencer = MapSequencer(addr_width=ceil_log2(self.map_depth), shape=self.map_word)
        wiring.connect(m, wiring.flipped(self.map_read), sequencer.read)
        m.submodules.output_queue = output_queue = CreditQueue(shape=p.surface_beat, depth=t.queue_depth)
        wiring.connect(m, output_queue.surface, wiring.flipped(self.surface))
        m.submodules.step_issue = steps = StepIssue(words=self.map_depth, flush_steps=t.flush_steps)
        m.d.comb += [
            steps.has_credit.eq(output_queue.has_credit),
            output_queue.issue.eq(steps.issue),
            # The sequencer's request carries a tag (of no bits here) beside the address.
            sequencer.request.valid.eq(steps.request.valid),
            sequencer.request.payload.addr.eq(steps.request.payload),
            steps.request.ready.eq(sequencer.request.ready),
            # Every word is taken on the edge after its request: nothing downstream stalls.
            sequencer.response.ready.eq(1),
        ]
        return sequencer, output_queue, steps

    def _window(self, m: Module, stages: PipelineStages, advance: Value, sequencer: MapSequencer, beats: BeatMetadata,
                step_is_word: Signal) -> tuple[StepWindow, int]:
        """The step register, the line buffers and the window register; returns it and the sums' first port.

        The columns the lanes' sums start on sit ``window_to_quotient`` steps of L columns above those
        their terms take (by then the same columns have moved down the register). Between them the steps
        no lane reads (``lead + 1`` steps hold a lane's terms' columns) are only a delay: block RAM, not
        registers (``stored``).
        """
        p, t = self._parameters, self._timing
        h, L = p.patch_shape[0], p.lanes
        top = stages.window_to_quotient * L
        bottom = t.lead + 1
        stored = range(bottom, stages.window_to_quotient) if stages.window_to_quotient - bottom >= 2 else range(0)
        m.submodules.window = window = StepWindow(lanes=L, rows=h, groups=t.groups, span=top + (t.lead + 1) * L,
                                                  depth_bits=p.depth_bits, stored=stored)
        sums_port = top - len(stored) * L  # the sums' first column among the window's ports
        m.d.comb += [
            window.advance.eq(advance),
            window.word.eq(sequencer.response.payload.data),
            window.group.eq(beats.group),
            window.next_group.eq(beats.next_group),
            window.is_word.eq(step_is_word),
        ]
        return window, sums_port

    def _lanes(self, m: Module, patch: PatchPreparation, window: StepWindow, sums_port: int, advance: Value) -> list:
        """The lanes, lane ``q`` on the window's columns ``q ...``; returns their values."""
        p = self._parameters
        w = p.patch_shape[1]
        lane_values = []
        for q in range(p.lanes):
            m.submodules[f"lane{q}"] = lane = WindowLane(parameters=p, product=self._product)
            m.d.comb += [
                lane.advance.eq(advance),
                *(lane.sum_window[l].eq(window.columns[sums_port + q + l]) for l in range(w)),
                *(lane.term_window[l].eq(window.columns[q + l]) for l in range(w)),
                # The lane's resets are ~patch_valid: the copy holds them, so no inverter is left.
                lane.patch_valid.eq(~patch.lane_patch_invalid[q]),
                lane.lifted_patch.eq(patch.lifted_patch),
                lane.mean_compensation.eq(patch.mean_compensation),
                lane.factor.eq(patch.factor),
                lane.dividend_bias.eq(patch.dividend_bias),
            ]
            lane_values.append(lane.value)
        return lane_values

    def _output(self, m: Module, output_queue: CreditQueue, beats: BeatMetadata, lane_values: list) -> None:
        """Into the output queue; a credit comes back with each step leaving without a beat."""
        last_meta = beats.beat
        beat = output_queue.write.payload
        m.d.comb += [
            beat.i.eq(last_meta.i),
            beat.j.eq(last_meta.j),
            beat.count.eq(last_meta.count),
            beat.last.eq(last_meta.last),
            output_queue.write.valid.eq(beats.write),
            output_queue.write_next.eq(beats.write_next),
            output_queue.passed.eq(beats.passed),
        ]
        m.d.comb += [beat.values[q].eq(Mux(q < last_meta.count, lane_values[q], 0)) for q in range(self._parameters.lanes)]

    def _control(self, m: Module, idle: Signal, idle_next: Signal, start: Value, clearing: Signal,
                 patch: PatchPreparation, steps: StepIssue, output_queue: CreditQueue) -> None:
        """The state machine (idle, the patch pass, the run); ``clearing`` resets the queue and the steps.

        ``idle`` is high in ``IDLE``; ``idle_next`` is its value on the next edge.
        """
        m.d.comb += [output_queue.clear.eq(clearing), steps.clear.eq(clearing)]
        with m.FSM():
            with m.State("IDLE"):
                m.d.comb += [idle.eq(1), idle_next.eq(~start)]
                with m.If(start):
                    m.next = "PREPARE"
            with m.State("PREPARE"):
                with m.If(patch.done):
                    m.d.comb += steps.begin.eq(1)
                    m.next = "RUN"
            with m.State("RUN"):
                with m.If(self.surface.valid & self.surface.ready & self.surface.payload.last):
                    m.d.comb += idle_next.eq(1)
                    m.next = "IDLE"


class WindowCorrelator(wiring.Component):
    """The window correlator with its map memory, map loader and best-fit reducer.

    Throughput and latency, with ``surface.ready`` and ``best.ready`` high: one memory row (``L``
    words) and one beat of ``L`` placements per clock once the pipeline is full; a correlation takes
    ``hw + 5 + H * ceil(W / L) + output_delay`` cycles to its last surface beat (one more when a
    row's last beat wraps to the next row's first step), then the reducer's pipeline and scan.
    Every beat's cycle is :func:`lost.model.cycles_window.schedule`;
    ``output_delay = 2 * ceil(log2(h * w)) + 9 + QUOTIENT_STAGES``.

    Parameters
    ----------
    map_shape : (int, int)
        ``(H, W)``, the terrain map stored in the core's memory.
    patch_shape : (int, int)
        ``(h, w)``, the sonar patch; no larger than the map.
    depth_bits : int
        Width of a depth word.
    lanes : int
        ``L``, placements computed per clock and values per surface beat; the map memory holds ``L``
        words per row, each map row padded to a multiple of ``L``.
    exclusion_radius : int
        Chebyshev radius around the best fit outside which the runner-up is searched.
    enable_buffer : callable or None
        ``enable_buffer(m, enable) -> Value``: how the step enable, a register that reaches every
        register of the step-synchronous stages, is carried to them; ``None`` (the default, and every
        simulation) uses the register's own net. A device-specific choice, made by whoever builds for
        a device: the synthesis flow passes the ECP5's global buffer
        (:func:`lost.hdl.flow.harness.ecp5_global_buffer`).
    product : ProductBlock
        How each lane makes the multipliers of its value, ``product(a_bits, b_bits)``: a component of
        :class:`~lost.hdl.blocks.RegisteredProduct`'s members and timing (the default, and every
        simulation). Also a device's choice: the synthesis flow passes ECP5 multipliers that hold the
        operands' registers (:class:`lost.hdl.flow.harness.ECP5RegisteredProduct`).

    Members
    -------
    map_in, patch_in, start, surface, best, busy
        See :func:`lost.hdl.interface.correlator_signature`.

    Raises
    ------
    ValueError
        See :class:`lost.hdl.interface.CorrelatorParameters`.
    """

    def __init__(self, *, map_shape, patch_shape, depth_bits: int = 16, lanes: int = 1, exclusion_radius: int = 1,
                 enable_buffer: EnableBuffer | None = None, product: ProductBlock = RegisteredProduct):
        self._enable_buffer = _checked_choice("enable_buffer", enable_buffer, "(module, enable) -> Value", optional=True)
        self._product = _checked_choice("product", product, "(a_bits, b_bits) -> a RegisteredProduct's like")
        self._parameters = CorrelatorParameters(
            map_shape=map_shape, patch_shape=patch_shape, depth_bits=depth_bits, lanes=lanes,
            exclusion_radius=exclusion_radius)
        super().__init__(correlator_signature(self._parameters))

    @property
    def parameters(self) -> CorrelatorParameters:
        return self._parameters

    @property
    def timing(self) -> WindowTiming:
        p = self._parameters
        return window_timing(p.map_shape, p.patch_shape, p.lanes)

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        p = self._parameters
        (_, W), L = p.map_shape, p.lanes

        m.submodules.core = core = WindowCore(
            map_shape=p.map_shape, patch_shape=p.patch_shape, depth_bits=p.depth_bits, lanes=L,
            exclusion_radius=p.exclusion_radius, enable_buffer=self._enable_buffer, product=self._product)
        m.submodules.map_memory = map_memory = memory.Memory(
            shape=core.map_word, depth=core.map_depth, init=[])
        wiring.connect(m, core.map_read, map_memory.read_port())

        # The loader: word c of map row r goes to lane c % L of memory row r * ceil(W / L) + c // L.
        write = map_memory.write_port(granularity=1)
        row_base = Signal(range(core.map_depth + 1))
        group = Signal(index_range(core.timing.groups))
        lane = Signal(index_range(L))
        column = Signal(index_range(W))
        loading = self.map_in.valid & self.map_in.ready
        m.d.comb += [
            self.map_in.ready.eq(~core.busy),
            write.addr.eq(row_base + group),
            write.en.eq(Mux(loading, 1 << lane, 0)),
        ]
        m.d.comb += [write.data[q].eq(self.map_in.payload) for q in range(L)]
        with m.If(loading):
            with m.If(column == W - 1):
                m.d.sync += [column.eq(0), lane.eq(0), group.eq(0)]
                with m.If(row_base == core.map_depth - core.timing.groups):
                    m.d.sync += row_base.eq(0)
                with m.Else():
                    m.d.sync += row_base.eq(row_base + core.timing.groups)
            with m.Else():
                m.d.sync += column.eq(column + 1)
                with m.If(lane == L - 1):
                    m.d.sync += [lane.eq(0), group.eq(group + 1)]
                with m.Else():
                    m.d.sync += lane.eq(lane + 1)
        with m.If(self.start.valid & self.start.ready):
            # A fresh correlation: a half-loaded map is abandoned, the next map starts at its origin.
            m.d.sync += [row_base.eq(0), group.eq(0), lane.eq(0), column.eq(0)]

        wiring.connect(m, wiring.flipped(self.patch_in), core.patch_in)
        wiring.connect(m, wiring.flipped(self.start), core.start)
        wiring.connect(m, core.surface, wiring.flipped(self.surface))
        wiring.connect(m, core.best, wiring.flipped(self.best))
        m.d.comb += self.busy.eq(core.busy)
        return m
