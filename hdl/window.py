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
invalid node's held at zero by its synchronous reset); the dividend follows, then the quotient by
restoring division over :data:`~lost.model.cycles_window.QUOTIENT_STAGES` stages; the terms are formed
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
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from amaranth.hdl import Cat, Const, Module, Mux, Shape, Signal, Value, signed, unsigned
from amaranth.lib import data, memory, wiring
from amaranth.lib.fifo import SyncFIFO
from amaranth.lib.wiring import In
from amaranth.utils import ceil_log2

from lost.hdl.blocks import AdderTree, DelayLine, Replicas, shape_for
from lost.hdl.interface import CorrelatorParameters, correlator_signature
from lost.hdl.reducer import BestFitReducer
from lost.hdl.sequencer import MapSequencer
from lost.model.cycles_window import QUOTIENT_STAGES, WindowTiming, window_timing

__all__ = ["PipelineStages", "WindowCore", "WindowCorrelator"]


def _index(count: int) -> range:
    """The range of an index below ``count``, at least one bit wide (Verilog has no empty vector)."""
    return range(max(count, 2))


#: The operand width of the device's multipliers (the ECP5's MULT18X18D): a product's wide operand is
#: split there, so that each partial product is one multiplier with registers on both sides.
_MULTIPLIER_BITS = 18


def _pipelined_quotient(m: Module, enable: Any, dividend: Any, divisors: list, quotient_bits: int, stages: int,
                        carry: Any, holds: list, name: str) -> tuple[list, Any]:
    """``floor(dividend / divisor)`` by restoring division in ``stages`` registers loaded on ``enable``.

    The dividend must be below ``divisor * 2**quotient_bits`` (so the first remainder, ``dividend >>
    quotient_bits``, is below the divisor) and the divisor must hold still; ``divisors`` are copies of
    it, each serving a run of the stages. Each stage takes ``ceil(quotient_bits / stages)`` quotient
    bits (the last fewer, or none), so the latency is ``stages`` whatever the width. One register per
    stage holds the dividend bits still to take and, shifted in behind them, the quotient bits made;
    ``carry`` travels beside. The last stage's quotient is loaded into one register per signal in
    ``holds``, held at zero while its signal is high: copies for a wide fan-out, which distinct resets
    keep synthesis from merging. Returns those copies and ``carry``, ``stages`` loads later.
    """
    per_stage = -(-quotient_bits // stages)
    divisor_bits = len(divisors[0])
    remainder_shape = unsigned(divisor_bits)
    remainder = dividend[quotient_bits:][:divisor_bits]
    bits = dividend[:quotient_bits]
    left = quotient_bits
    for stage in range(stages):
        divisor = divisors[stage * len(divisors) // stages]
        for _ in range(min(per_stage, left)):
            trial = Cat(bits[-1], remainder)  # 2 * remainder + the next dividend bit
            reduced = trial - divisor
            # The divisor fits when the difference is not negative: its sign is a sum bit of the
            # carry chain, where a comparison's carry out would be rebuilt in LUTs.
            fits = ~reduced[-1]
            remainder = Mux(fits, reduced, trial)[:divisor_bits]
            bits = Cat(fits, bits[:-1])
            left -= 1
        registers = Signal(data.StructLayout({"remainder": remainder_shape, "bits": unsigned(quotient_bits),
                                              "carry": Shape.cast(carry.shape())}),
                           name=f"{name}_s{stage}", reset_less=True)
        with m.If(enable):
            m.d.sync += [registers.remainder.eq(remainder), registers.carry.eq(carry)]
            if stage < stages - 1:
                m.d.sync += registers.bits.eq(bits)
        if stage == stages - 1:
            break
        remainder, bits, carry = registers.remainder, registers.bits, registers.carry
    quotients = [Signal(unsigned(quotient_bits), name=f"{name}_copy{c}", reset_less=True) for c in range(len(holds))]
    for quotient, hold in zip(quotients, holds):
        with m.If(hold):
            m.d.sync += quotient.eq(0)
        with m.Elif(enable):
            m.d.sync += quotient.eq(bits)
    return quotients, registers.carry


@dataclass(frozen=True)
class PipelineStages:
    """The window pipeline's stages by name: where each register of a placement's path sits.

    Step-synchronous stages are counted in steps from the one that takes a map word (1), term stages
    in clocks after the last step-synchronous one (1 is the first term stage). The model's
    :class:`~lost.model.cycles_window.WindowTiming` counts them (``step_stages``, ``term_stages``);
    :meth:`of` checks that both agree.
    """

    #: Step-synchronous: the step register, the window register (whose bottom the terms read), the masked
    #: depths, the last window-sum level, the dividend, the last quotient stage (= ``step_stages``).
    step: int
    window: int
    masked: int
    window_sum: int
    dividend: int
    quotient: int
    #: Every clock: the lifted differences, the selected ones and their count, the last level of their
    #: sums (with the dividend beside it), the partial products (with the correction), their sums, the
    #: value (= ``term_stages``).
    difference: int
    selected: int
    sums: int
    partials: int
    totals: int
    value: int

    @classmethod
    def of(cls, timing: WindowTiming) -> PipelineStages:
        levels = timing.sum_levels
        window_sum = 3 + levels
        sums = 2 + levels
        stages = cls(step=1, window=2, masked=3, window_sum=window_sum, dividend=window_sum + 1,
                     quotient=window_sum + 1 + QUOTIENT_STAGES, difference=1, selected=2, sums=sums,
                     partials=sums + 1, totals=sums + 2, value=sums + 3)
        if (stages.quotient, stages.value) != (timing.step_stages, timing.term_stages):
            raise AssertionError(f"the gateware's stages {stages} disagree with the cycle model's {timing}")
        return stages


#: How a high-fan-out enable reaches its loads: ``(module, enable) -> the value the loads see``.
EnableBuffer = Callable[[Module, Value], Value]


def _check_enable_buffer(enable_buffer: Any) -> EnableBuffer | None:
    if enable_buffer is not None and not callable(enable_buffer):
        raise ValueError(f"enable_buffer must be None or a function (module, enable) -> Value, got {enable_buffer!r}")
    return enable_buffer


class WindowCore(wiring.Component):
    """The window correlator without its map memory, which it reads through ``map_read``.

    Parameters
    ----------
    map_shape, patch_shape, depth_bits, lanes, exclusion_radius, enable_buffer
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
                 enable_buffer: EnableBuffer | None = None):
        self._enable_buffer = _check_enable_buffer(enable_buffer)
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
        p, t = self._parameters, self._timing
        (H, _), (h, w), L, b = p.map_shape, p.patch_shape, p.lanes, p.depth_bits
        widths = p.widths
        nodes = h * w
        Ho, Wo = p.surface_shape
        G = t.groups
        stages = PipelineStages.of(t)

        depth = signed(b)
        count = unsigned(widths.count.bits)
        window_sum = signed(widths.window_sum.bits)
        # Lifted: 2**b - S, M - S + 2**b and the quotient all lie in [1, 2**(b+1) - 1].
        lift = 1 << b
        lifted = unsigned(b + 1)
        lifted_sum_hi = nodes * (2 * lift - 1)
        # The dividend N = sum_valid M - Ssum + f * 2**b with mean compensation; without it the same
        # register carries sum_valid M - Ssum (the correction), the dividend being 2**b.
        carried = shape_for(widths.sum_difference.lo, lifted_sum_hi)
        bias = shape_for(-nodes * widths.depth.hi, nodes * (lift - widths.depth.lo))
        value_bits = widths.accumulator.bits
        # The quotient meets every node's comparator: one register would drive h * w of them across a
        # lane, so each lane keeps a copy per ``copy_nodes`` consecutive nodes (a patch row of Nygren's
        # 10 x 10, whose comparators sit together), loaded from one of ``sources`` copies of the
        # divider's last stage, each serving ``per_source`` of them: a fan-out of a few at each level.
        # A copy is held at zero while none of its nodes is valid (it is then unused): distinct resets
        # keep synthesis from merging the copies.
        copy_nodes = 10
        copies = -(-nodes // copy_nodes)
        sources = ceil_log2(copies) if copies > 2 else 1
        per_source = -(-copies // sources)

        # ---- the patch, its count and sum, and its lifted depths 2**b - S (formed at start) -----------
        # Like the map memory, the patch persists through a reset until reloaded. Its depths, read one
        # node per clock by the pass at start, live in a small memory; its valid bits, which every
        # lane needs at once, in a reset-less register.
        m.submodules.patch_memory = patch_memory = memory.Memory(shape=depth, depth=nodes, init=[])
        patch_write = patch_memory.write_port()
        patch_read = patch_memory.read_port()
        patch_valid = Signal(nodes, reset_less=True)
        lifted_patch = Signal(data.ArrayLayout(lifted, nodes), reset_less=True)
        group_valid = [patch_valid[c * copy_nodes:(c + 1) * copy_nodes].any() for c in range(copies)]
        source_valid = [patch_valid[s * per_source * copy_nodes:(s + 1) * per_source * copy_nodes].any()
                        for s in range(sources)]
        mean_compensation = Signal()
        valid_count = Signal(count)
        patch_sum = Signal(window_sum)
        factor = Signal(count)
        dividend_bias = Signal(bias)  # f * 2**b - Ssum with mean compensation, -Ssum without

        idle = Signal()
        m.submodules.reducer = reducer = BestFitReducer(parameters=p)
        ready_for_more = idle & ~reducer.busy
        m.d.comb += [
            self.patch_in.ready.eq(ready_for_more),
            self.start.ready.eq(ready_for_more),
            self.busy.eq(~ready_for_more),
        ]

        # Patch words since the last start (or reset) fill nodes 0, 1, ...; the valid bits shift in.
        patch_pointer = Signal(_index(nodes))
        loading = self.patch_in.valid & self.patch_in.ready
        m.d.comb += [
            patch_write.addr.eq(patch_pointer),
            patch_write.data.eq(self.patch_in.payload.depth),
            patch_write.en.eq(loading),
        ]
        with m.If(loading):
            m.d.sync += patch_pointer.eq(Mux(patch_pointer == nodes - 1, 0, patch_pointer + 1))
            m.d.sync += [patch_valid[x].eq(patch_valid[x + 1]) for x in range(nodes - 1)]
            m.d.sync += patch_valid[nodes - 1].eq(self.patch_in.payload.valid)

        # ---- the steps: one map read or flush step issued per credit, taken on the next edge ----------
        m.submodules.sequencer = sequencer = MapSequencer(
            addr_width=ceil_log2(self.map_depth), shape=self.map_word)
        wiring.connect(m, wiring.flipped(self.map_read), sequencer.read)

        # The output queue holds every beat the pipeline can still write: a step is issued only against
        # a credit, returned when its beat leaves the queue (or when it leaves the pipeline without a
        # beat), so the lanes never wait for ``surface.ready``. The queue adds no latency: a beat
        # written on one edge can transfer on the next.
        m.submodules.output_queue = output_queue = SyncFIFO(
            width=Shape.cast(p.surface_beat).width, depth=t.queue_depth)
        m.d.comb += [
            self.surface.valid.eq(output_queue.r_rdy),
            self.surface.payload.eq(output_queue.r_data),
            output_queue.r_en.eq(self.surface.ready),
        ]

        issuing = Signal()  # steps of this correlation are left to issue
        issuing_words = Signal()  # ... and map words among them
        request_addr = Signal(range(self.map_depth + 1))
        flush_left = Signal(range(t.flush_steps + 1))
        credits = Signal(range(t.queue_depth + 1))
        issue = Signal()
        m.d.comb += [
            issue.eq(issuing & (credits != 0) & (sequencer.request.ready | ~issuing_words)),
            sequencer.request.valid.eq(issuing & issuing_words & (credits != 0)),
            sequencer.request.payload.addr.eq(request_addr),
            # Every word is taken on the edge after its request: nothing downstream stalls.
            sequencer.response.ready.eq(1),
        ]
        with m.If(issue):
            with m.If(issuing_words):
                m.d.sync += request_addr.eq(request_addr + 1)
                with m.If(request_addr == self.map_depth - 1):
                    m.d.sync += issuing_words.eq(0)
            with m.Else():
                m.d.sync += flush_left.eq(flush_left - 1)
                with m.If(flush_left == 1):
                    m.d.sync += issuing.eq(0)

        # ``advance`` is a register: the only enable of the step-synchronous stages (step register,
        # line buffers, window register, masked depths, window-sum tree, dividend, quotient stages);
        # the lanes' term stages run every clock.
        advance_register = Signal()
        step_is_word = Signal()
        m.d.sync += [advance_register.eq(issue), step_is_word.eq(issue & issuing_words)]
        advance = advance_register if self._enable_buffer is None else self._enable_buffer(m, advance_register)

        step_row = Signal(range(H + t.flush_steps + 2))
        step_group = Signal(_index(G))
        with m.If(advance):
            with m.If(step_group == G - 1):
                m.d.sync += [step_group.eq(0), step_row.eq(step_row + 1)]
            with m.Else():
                m.d.sync += step_group.eq(step_group + 1)

        # ---- the beat a step completes (known when the step is taken) -------------------------------
        meta_layout = data.StructLayout({
            "live": 1, "emit": 1, "i": unsigned(p.row_bits), "j": unsigned(p.col_bits),
            "count": p.surface_beat["count"].shape, "last": 1,
        })
        normal = (step_row >= h - 1) & (step_row <= H - 1) & (step_group >= t.lead)
        wrapped = Const(t.wraps) & (step_group == 0) & (step_row >= h) & (step_row <= H)
        beat_row = Mux(normal, step_row - (h - 1), step_row - h)
        beat_group = Mux(normal, step_group - t.lead, t.out_groups - 1)
        step_meta = Signal(meta_layout)
        m.d.comb += [
            step_meta.live.eq(1),
            step_meta.emit.eq(normal | wrapped),
            step_meta.i.eq(beat_row),
            step_meta.j.eq(beat_group * L),
            step_meta.count.eq(Mux(beat_group == t.out_groups - 1, Wo - (t.out_groups - 1) * L, L)),
            step_meta.last.eq((beat_row == Ho - 1) & (beat_group == t.out_groups - 1)),
        ]

        # ---- step register: the words and their beat ----------------------------------------------
        row_layout = data.ArrayLayout(depth, L)
        step_nodes = Signal(row_layout, reset_less=True)
        step_group_reg = Signal(_index(G))
        step_was_word = Signal()
        # The beat of each step-synchronous stage.
        sync_meta = Signal(data.ArrayLayout(meta_layout, stages.quotient), reset_less=True)
        with m.If(advance):
            m.d.sync += [
                step_group_reg.eq(step_group),
                step_was_word.eq(step_is_word),
                sync_meta[0].eq(step_meta),
            ]
            m.d.sync += step_nodes.eq(sequencer.response.payload.data)
            for x in range(1, stages.quotient):
                m.d.sync += sync_meta[x].eq(sync_meta[x - 1])

        # ---- line buffers: rows r-1 .. r-h+1 of the group being taken ------------------------------
        # Each is a delay of G steps. A block RAM's output is slow, so it is read one step ahead (the
        # next step's group) into a register that loads with the step, and the next line buffer is
        # written from that register: no path runs from one block RAM to another. With G >= 3 the
        # entry read was written at least one step before, so the read port needs no transparency; a
        # delay of one or two steps is a register or two.
        read_ahead = Mux(step_group == G - 1, 0, step_group + 1)
        buffer_rows = []
        for x in range(h - 1):
            entering = step_nodes if x == 0 else buffer_rows[x - 1]
            registers = G if G <= 2 else 1
            delayed = [Signal(row_layout, name=f"line_buffer_{x}_out{y}", reset_less=True) for y in range(registers)]
            if G <= 2:
                with m.If(advance):
                    m.d.sync += [delayed[y].eq(delayed[y - 1] if y else entering) for y in range(G)]
            else:
                line = memory.Memory(shape=row_layout, depth=G, init=[])
                m.submodules[f"line_buffer_{x}"] = line
                write = line.write_port()
                read = line.read_port()
                m.d.comb += [
                    read.addr.eq(read_ahead),
                    read.en.eq(advance),
                    write.addr.eq(step_group_reg),
                    write.en.eq(advance & step_was_word),
                    write.data.eq(entering),
                ]
                with m.If(advance):
                    m.d.sync += delayed[0].eq(read.data)
            buffer_rows.append(delayed[-1])

        # ---- window register: columns, oldest first; the newest L enter on the right ---------------
        # The quotient takes quotient - window steps after the window register (the masked depths, the
        # window-sum tree, the dividend, the quotient stages): the columns its lanes start on sit that
        # many steps of L columns above those the terms take.
        top = (stages.quotient - stages.window) * L
        span = top + (t.lead + 1) * L
        # One signal per column: fewer signals than one per node, while the Python simulator (whose
        # generated code spells masks as decimal literals) still handles their width.
        window = [Signal(data.ArrayLayout(depth, h), name=f"window_{c}", reset_less=True) for c in range(span)]
        with m.If(advance):
            for c in range(span - L):
                for k in range(h):
                    m.d.sync += window[c][k].eq(window[c + L][k])
            for q in range(L):
                column = [buffer_rows[h - 2 - k][q] for k in range(h - 1)] + [step_nodes[q]]
                for k in range(h):
                    m.d.sync += window[span - L + q][k].eq(column[k])

        # ---- the term stages run every clock; a valid bit says which state is a new step -------------
        # ``fresh``: the last edge was a step, so the window's bottom and the window sums hold a new
        # placement; otherwise the lanes recompute the previous one and their result is dropped.
        fresh = Signal()
        m.d.sync += fresh.eq(advance)
        # Only the valid bits need a reset: after one, no stale step may reach the queue.
        m.submodules.term_meta = term_meta = DelayLine(meta_layout, stages.value, reset_less=True)
        m.submodules.term_valid = term_valid = DelayLine(1, stages.value)
        m.d.comb += [term_meta.i.eq(sync_meta[stages.quotient - 1]), term_valid.i.eq(fresh)]

        # ---- the lanes ------------------------------------------------------------------------------
        lane_values = []
        for q in range(L):
            # The mode and f reach much of a lane: each lane has registers of its own for them, one for
            # each of its parts (the dividend, each run of quotient stages, the products).
            m.submodules[f"lane{q}_mode"] = modes = Replicas(1, 2)
            m.d.comb += modes.i.eq(mean_compensation)
            mode, term_mode = modes.o[0], modes.o[1]
            divider_copies = -(-QUOTIENT_STAGES // 6)
            m.submodules[f"lane{q}_factor"] = factors = Replicas(count, divider_copies + 1)
            m.d.comb += factors.i.eq(factor)
            divisors = [factors.o[r] for r in range(divider_copies)]
            lane_factor = factors.o[divider_copies]
            # Window sum of the valid nodes, on the columns as they arrive (step-synchronous). An
            # invalid node's depth register is held at zero by its synchronous reset: no LUT per bit.
            masked = Signal(data.ArrayLayout(depth, nodes), name=f"lane{q}_masked", reset_less=True)
            for k in range(h):
                for l in range(w):
                    x = k * w + l
                    with m.If(~patch_valid[x]):
                        m.d.sync += masked[x].eq(0)
                    with m.Elif(advance):
                        m.d.sync += masked[x].eq(window[top + q + l][k])
            m.submodules[f"lane{q}_wsum"] = wsum_tree = AdderTree(
                count=nodes, leaf=(widths.depth.lo, widths.depth.hi), total=(widths.window_sum.lo, widths.window_sum.hi),
                enable=True)
            m.d.comb += [wsum_tree.en.eq(advance), *(wsum_tree.leaves[x].eq(masked[x]) for x in range(nodes))]
            wsum = wsum_tree.sum
            # The dividend (or the correction), then t + 2**b = floor(N / f) over the quotient stages.
            carried_in = Signal(carried, name=f"lane{q}_carried_in", reset_less=True)
            with m.If(advance):
                m.d.sync += carried_in.eq(wsum + dividend_bias)
            quotients, carried_out = _pipelined_quotient(
                m, advance, Mux(mode, carried_in, lift), divisors, b + 1, QUOTIENT_STAGES, carried_in,
                [~valid for valid in source_valid], f"lane{q}_quotient")

            # The same columns, quotient - window steps later, at the bottom of the register: the lifted
            # differences M - S + 2**b, those above the quotient (d > t) and their count, their sums.
            quotient_copy = [Signal(lifted, name=f"lane{q}_quotient{c}", reset_less=True) for c in range(copies)]
            for c in range(copies):
                with m.If(~group_valid[c]):
                    m.d.sync += quotient_copy[c].eq(0)
                with m.Else():
                    m.d.sync += quotient_copy[c].eq(quotients[c // per_source])
            # The dividend (or the correction) beside the term stages, up to the one before the partials.
            m.submodules[f"lane{q}_carried"] = carried_line = DelayLine(carried, stages.sums, reset_less=True)
            m.d.comb += carried_line.i.eq(carried_out)
            carried_at = list(carried_line.taps)  # carried_at[stage - 1]: the carried value of that stage
            difference = Signal(data.ArrayLayout(lifted, nodes), name=f"lane{q}_difference", reset_less=True)
            above = Signal(data.ArrayLayout(lifted, nodes), name=f"lane{q}_above", reset_less=True)
            selected = Signal(nodes, name=f"lane{q}_selected", reset_less=True)
            for k in range(h):
                for l in range(w):
                    x = k * w + l
                    # d' > q as the sign of q - d': a sum bit of the carry chain, where a comparison's
                    # carry out would be rebuilt in LUTs.
                    chosen = patch_valid[x] & (quotient_copy[x // copy_nodes] - difference[x])[-1]
                    m.d.sync += [
                        difference[x].eq(window[q + l][k] + lifted_patch[x]),
                        # A register's synchronous reset: one LUT per node, none per bit.
                        above[x].eq(Mux(chosen, difference[x], 0)),
                        selected[x].eq(chosen),
                    ]
            m.submodules[f"lane{q}_above_sum"] = above_tree = AdderTree(
                count=nodes, leaf=(0, 2 * lift - 1), total=(0, lifted_sum_hi))
            m.submodules[f"lane{q}_above_count"] = count_tree = AdderTree(count=nodes, leaf=(0, 1), total=(0, nodes))
            m.d.comb += [above_tree.leaves[x].eq(above[x]) for x in range(nodes)]
            m.d.comb += [count_tree.leaves[x].eq(selected[x]) for x in range(nodes)]
            above_sum, above_count = above_tree.sum, count_tree.sum
            # V = 2 * (f * P' - K * N) - correction, modulo 2**value_bits (V is below it, so exact): the
            # dividend beside the sums' last level, then each product as two partial products of a
            # multiplier's width, then their sums (with the correction), then V.
            dividend = Signal(lifted_sum_hi.bit_length(), name=f"lane{q}_dividend", reset_less=True)
            m.d.sync += dividend.eq(Mux(term_mode, carried_at[stages.sums - 2], lift))
            correction = Signal(carried, name=f"lane{q}_correction", reset_less=True)
            m.d.sync += correction.eq(Mux(term_mode, 0, carried_at[stages.partials - 2]))
            partials = Signal(data.ArrayLayout(unsigned(value_bits), 4), name=f"lane{q}_partials", reset_less=True)
            m.d.sync += [
                partials[0].eq(lane_factor * above_sum[:_MULTIPLIER_BITS]),
                partials[1].eq(lane_factor * above_sum[_MULTIPLIER_BITS:]),
                partials[2].eq(above_count * dividend[:_MULTIPLIER_BITS]),
                partials[3].eq(above_count * dividend[_MULTIPLIER_BITS:]),
            ]
            doubled_sum = Signal(value_bits, name=f"lane{q}_doubled_sum", reset_less=True)
            count_product = Signal(value_bits, name=f"lane{q}_count_product", reset_less=True)
            m.d.sync += [
                doubled_sum.eq(((partials[0] + (partials[1] << _MULTIPLIER_BITS)) << 1) - correction),
                count_product.eq(partials[2] + (partials[3] << _MULTIPLIER_BITS)),
            ]
            value = Signal(unsigned(value_bits), name=f"lane{q}_value", reset_less=True)
            m.d.sync += value.eq(doubled_sum - (count_product << 1))
            lane_values.append(value)

        # ---- into the output queue ---------------------------------------------------------------------
        last_meta = term_meta.o
        last_valid = term_valid.o & last_meta.live
        beat = Signal(p.surface_beat)
        m.d.comb += [
            beat.i.eq(last_meta.i),
            beat.j.eq(last_meta.j),
            beat.count.eq(last_meta.count),
            beat.last.eq(last_meta.last),
            output_queue.w_data.eq(beat),
            output_queue.w_en.eq(last_valid & last_meta.emit),
        ]
        m.d.comb += [beat.values[q].eq(Mux(q < last_meta.count, lane_values[q], 0)) for q in range(L)]
        # A credit comes back with each beat leaving the queue and each step leaving without a beat.
        returned = (last_valid & ~last_meta.emit) + (output_queue.r_rdy & output_queue.r_en)
        m.d.sync += credits.eq(credits - issue + returned)

        # The reducer watches the surface's transfers (registering each before any logic, so the
        # queue's read stays out of its paths) and answers on ``best``.
        m.d.comb += [
            reducer.surface.valid.eq(self.surface.valid & self.surface.ready),
            reducer.surface.payload.eq(self.surface.payload),
        ]
        wiring.connect(m, reducer.best, wiring.flipped(self.best))

        # ---- control ----------------------------------------------------------------------------------
        prepare_step = Signal(range(nodes + 2))
        lifting = Signal()  # the pass takes a node: n, Ssum and lifted_patch (cycles 3 .. hw + 2)
        # The patch is read in place (not rotated), so a reset mid-pass leaves it intact; the memory's
        # read register and one after it (a block RAM's output is slow) keep the pass's paths short.
        node = Signal(_index(nodes))
        with m.If(idle | (node == nodes - 1)):
            m.d.sync += node.eq(0)
        with m.Else():
            m.d.sync += node.eq(node + 1)
        head_read = Signal(depth)
        head_depth = Signal(depth)
        head_valid_read = Signal()
        head_valid = Signal()
        m.d.comb += [patch_read.addr.eq(node), head_read.eq(patch_read.data)]
        m.d.sync += [
            head_valid_read.eq(patch_valid.bit_select(node, 1)),
            head_depth.eq(head_read),
            head_valid.eq(head_valid_read),
        ]
        # Outside the state machine, so that a register alone enables the pass's registers.
        with m.If(lifting):
            m.d.sync += [lifted_patch[x].eq(lifted_patch[x + 1]) for x in range(nodes - 1)]
            m.d.sync += [
                lifted_patch[nodes - 1].eq(lift - head_depth),
                valid_count.eq(valid_count + head_valid),
                patch_sum.eq(patch_sum + Mux(head_valid, head_depth, 0)),
            ]
        with m.If(idle):
            m.d.sync += [valid_count.eq(0), patch_sum.eq(0), prepare_step.eq(0)]
        # The run's counters are cleared while idle (and on the pass's first cycle) by a register of their
        # own, so that the start beat's condition reaches only the pass's few registers.
        clearing = Signal(init=1)
        m.d.sync += clearing.eq(idle)
        with m.If(clearing):
            m.d.sync += [
                request_addr.eq(0),
                flush_left.eq(t.flush_steps),
                credits.eq(t.queue_depth),
                step_row.eq(0),
                step_group.eq(0),
            ]
            # The step-synchronous stages may still hold the last correlation's flush steps.
            m.d.sync += [sync_meta[x].live.eq(0) for x in range(stages.quotient)]
        with m.FSM():
            with m.State("IDLE"):
                m.d.comb += idle.eq(1)
                with m.If(self.start.valid & self.start.ready):
                    m.d.sync += [
                        mean_compensation.eq(self.start.payload.mean_compensation),
                        patch_pointer.eq(0),
                    ]
                    m.next = "COUNT"
            with m.State("COUNT"):
                # n, sum_valid S and the lifted depths, from node k - 2 on cycle k = 2 .. hw + 1.
                m.d.sync += prepare_step.eq(prepare_step + 1)
                with m.If(prepare_step == 1):
                    m.d.sync += lifting.eq(1)
                with m.If(prepare_step == nodes + 1):
                    m.d.sync += [
                        lifting.eq(0),
                        factor.eq(Mux(mean_compensation, valid_count + head_valid, 1)),
                    ]
                    m.next = "BIAS"
            with m.State("BIAS"):
                m.d.sync += [
                    dividend_bias.eq(Mux(mean_compensation, factor << b, 0) - patch_sum),
                    issuing.eq(1),
                    issuing_words.eq(1),
                ]
                m.next = "RUN"
            with m.State("RUN"):
                with m.If(self.surface.valid & self.surface.ready & self.surface.payload.last):
                    m.next = "IDLE"

        return m


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
                 enable_buffer: EnableBuffer | None = None):
        self._enable_buffer = _check_enable_buffer(enable_buffer)
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
            exclusion_radius=p.exclusion_radius, enable_buffer=self._enable_buffer)
        m.submodules.map_memory = map_memory = memory.Memory(
            shape=core.map_word, depth=core.map_depth, init=[])
        wiring.connect(m, core.map_read, map_memory.read_port())

        # The loader: word c of map row r goes to lane c % L of memory row r * ceil(W / L) + c // L.
        write = map_memory.write_port(granularity=1)
        row_base = Signal(range(core.map_depth + 1))
        group = Signal(_index(core.timing.groups))
        lane = Signal(_index(L))
        column = Signal(_index(W))
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
