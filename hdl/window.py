"""The shift-register / window correlator: every lane produces one placement per clock.

Nygren's shift-register principle (FOI-R--0764--SE, section 8.2) made exact and streaming: the map is
read once per correlation, one memory row of ``L`` words per clock in raster order; ``h - 1`` line
buffers turn that stream into columns of ``h`` words; a window register of columns holds every
``h x w`` window that the ``L`` lanes need; each lane then forms its ``h * w`` terms and the sum of
their absolute values, with a register after every adder level.

The arithmetic follows :mod:`lost.model.correlator` rearranged so that nothing is computed per term
that can be computed once::

    term(k, l) = (f * M[i+k, j+l] - C[k, l]) - Wsum(i, j)     for a valid node (k, l), 0 otherwise
    C[k, l]    = f * S[k, l] - Ssum                           once per correlation, at start
    f          = n,  Ssum = sum_valid S,  Wsum = sum_valid M  with mean compensation
    f          = 1,  Ssum = 0,            Wsum = 0            without (in the terms)

``f * M`` is formed once per map word, as it leaves the memory, and travels beside ``M`` through the
line buffers. The window sum runs over the valid nodes only, so with a mask each column offset has its
own column sum and a sliding accumulator does not apply; per lane it costs ``h * w - 1`` adders either
as masked column sums plus a row sum or, as here, as one balanced tree. The tree starts on the columns
as soon as they enter the window register, from a register of the masked depths (an invalid node's
held at zero by its synchronous reset); the terms are formed ``ceil(log2(h * w)) + 1`` steps later from
the same columns, which have moved down the register by then, so neither the sum nor the terms need a
delay line.

No absolute value is formed. With mean compensation the terms of the valid nodes are deviations from
their mean and sum to zero, so ``V = sum |z| = 2 * sum max(z, 0)``; without it ``z = M - S`` and
``V = 2 * sum max(z, 0) - (sum_valid M - sum_valid S)``, the window sum (formed in both modes, subtracted
from the terms only with mean compensation) giving the correction. ``max(z, 0)`` of a valid node is
a register's synchronous reset, one LUT per node, where ``|z|`` costs an adder or a LUT per bit.

Only the step-synchronous stages (the step register, the line buffers, the window register, the masked
depths and the window-sum tree) hold still between steps; a step is a map word or, at the end, one of a fixed number
of flush steps. Their one enable is a register, ``advance``, set on the edge a step is issued. The
term stages (``f*M - C``, minus the window sum, ``max(z, 0)``, value tree) run on every clock with a valid
bit beside them: between steps they recompute the last placement, marked stale. Steps are issued
against credits for the output queue, one per beat it holds, so a beat always finds room and
``surface.ready`` stalls nothing but the issue of further steps. The cycles are modelled exactly by
:mod:`lost.model.cycles_window`, whose :func:`~lost.model.cycles_window.window_timing` gives the
pipeline its constants.
"""

from __future__ import annotations

from typing import Any

from amaranth.hdl import Const, Module, Mux, Shape, Signal, signed, unsigned
from amaranth.lib import data, memory, wiring
from amaranth.lib.fifo import SyncFIFO
from amaranth.lib.wiring import In
from amaranth.utils import ceil_log2

from lost.hdl.interface import CorrelatorParameters, correlator_signature
from lost.hdl.reducer import BestFitReducer
from lost.hdl.sequencer import MapSequencer
from lost.model.cycles_window import WindowTiming, window_timing
from lost.model.widths import bits_for

__all__ = ["WindowCore", "WindowCorrelator"]


def _union_bits(*bounds: tuple[int, int]) -> Shape:
    lo = min(b[0] for b in bounds)
    hi = max(b[1] for b in bounds)
    width, is_signed = bits_for(lo, hi)
    return signed(width) if is_signed else unsigned(width)


def _index(count: int) -> range:
    """The range of an index below ``count``, at least one bit wide (Verilog has no empty vector)."""
    return range(max(count, 2))


def _pipelined_sum(m: Module, enable: Any, values: list, leaf: tuple[int, int], cap: tuple[int, int], name: str) -> Any:
    """Sum ``values`` with a balanced adder tree, one register level per adder level.

    The registers load when ``enable`` is high, or on every clock when it is ``None``. They are
    reset-less, like every datapath register here: a reset would only add a net to thousands of them.

    Each register is as wide as the sums it can hold: ``k`` leaves in ``[leaf_lo, leaf_hi]`` give
    ``[k * leaf_lo, k * leaf_hi]``, never more than the bound ``cap`` of the whole sum.
    """
    level, leaves = 0, 1
    while len(values) > 1:
        # One array register per level (fewer, wider signals keep the generated Verilog small).
        leaves *= 2
        lo, hi = max(leaves * leaf[0], cap[0]), min(leaves * leaf[1], cap[1])
        sums = Signal(data.ArrayLayout(_union_bits((lo, hi)), (len(values) + 1) // 2), name=f"{name}_l{level}",
                      reset_less=True)
        loads = [sums[index // 2].eq(pair[0] + pair[1] if len(pair) == 2 else pair[0])
                 for index in range(0, len(values), 2) for pair in [values[index : index + 2]]]
        if enable is None:
            m.d.sync += loads
        else:
            with m.If(enable):
                m.d.sync += loads
        values = [sums[index] for index in range((len(values) + 1) // 2)]
        level += 1
    return values[0]


class WindowCore(wiring.Component):
    """The window correlator without its map memory, which it reads through ``map_read``.

    Parameters
    ----------
    map_shape, patch_shape, depth_bits, lanes, exclusion_radius
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

    def __init__(self, *, map_shape, patch_shape, depth_bits: int = 16, lanes: int = 1, exclusion_radius: int = 1):
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
        (H, W), (h, w), L, b = p.map_shape, p.patch_shape, p.lanes, p.depth_bits
        widths = p.widths
        nodes = h * w
        Ho, Wo = p.surface_shape
        G = t.groups

        depth = signed(b)
        count = unsigned(widths.count.bits)
        scaled = signed(widths.scaled_depth.bits)
        window_sum = signed(widths.window_sum.bits)
        # The window sum meets every node's subtractor: one register would drive h * w of them across a
        # lane, so each lane keeps ``copies`` registers of it, copy c holding Wsum + c (distinct, so that
        # synthesis keeps them apart) for the ``copy_nodes`` consecutive nodes x with x // copy_nodes == c
        # (a patch row of Nygren's 10 x 10, whose subtractors sit together), whose C is lowered by c.
        copy_nodes = 10
        copies = -(-nodes // copy_nodes)
        # Plain mode uses f = 1 and C = S, so every shape holds both modes' ranges.
        centred_lo = min(widths.centred_depth.lo, widths.depth.lo) - (copies - 1)
        centred_hi = max(widths.centred_depth.hi, widths.depth.hi)
        centred = _union_bits((centred_lo, centred_hi))
        offset = _union_bits((widths.scaled_depth.lo - centred_hi, widths.scaled_depth.hi - centred_lo))
        window_sum_copy = _union_bits((min(widths.window_sum.lo, 0), widths.window_sum.hi + copies - 1))
        term_max = max(widths.term.hi, widths.difference.hi)
        # A valid node's term lies within the bound, so truncating the full difference is exact.
        term = _union_bits((-term_max, term_max))
        abs_term = unsigned(term_max.bit_length())
        difference_sum = signed(widths.sum_difference.bits)

        # ---- the patch, its count and sum, and C = f * S - Ssum (formed at start) ----------------
        # Like the map memory, the patch persists through a reset until reloaded. Its depths, read one
        # node per clock by the two passes, live in a small memory; its valid bits, which every lane
        # needs at once, in a reset-less register.
        m.submodules.patch_memory = patch_memory = memory.Memory(shape=depth, depth=nodes, init=[])
        patch_write = patch_memory.write_port()
        patch_read = patch_memory.read_port()
        patch_valid = Signal(nodes, reset_less=True)
        centred_patch = Signal(data.ArrayLayout(centred, nodes), reset_less=True)
        mean_compensation = Signal()
        valid_count = Signal(count)
        patch_sum = Signal(window_sum)
        factor = Signal(count)

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

        running = Signal()
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
        # line buffers, window register, window-sum tree); the lanes' term stages run every clock.
        advance = Signal()
        step_is_word = Signal()
        m.d.sync += [advance.eq(issue), step_is_word.eq(issue & issuing_words)]

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

        # ---- step register: the word, f * word, and its beat ------------------------------------
        node_layout = data.StructLayout({"depth": depth, "scaled": scaled})
        row_layout = data.ArrayLayout(node_layout, L)
        step_nodes = Signal(row_layout, reset_less=True)
        step_group_reg = Signal(_index(G))
        step_was_word = Signal()
        # The beat of each step-synchronous stage: step register, window register, window-sum levels.
        sync_meta = Signal(data.ArrayLayout(meta_layout, t.step_stages), reset_less=True)
        with m.If(advance):
            m.d.sync += [
                step_group_reg.eq(step_group),
                step_was_word.eq(step_is_word),
                sync_meta[0].eq(step_meta),
            ]
            for q in range(L):
                word = sequencer.response.payload.data[q]
                m.d.sync += [step_nodes[q].depth.eq(word), step_nodes[q].scaled.eq(factor * word)]
            for x in range(1, t.step_stages):
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
            stages = G if G <= 2 else 1
            delayed = [Signal(row_layout, name=f"line_buffer_{x}_out{y}", reset_less=True) for y in range(stages)]
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
        # The window sum takes sum_levels + 1 steps (the masked depths, then the tree): the columns its
        # lanes start on sit that many steps of L columns above those the terms take.
        top = (t.sum_levels + 1) * L
        span = top + (t.lead + 1) * L
        # One signal per column: fewer signals than one per node, while the Python simulator (whose
        # generated code spells masks as decimal literals) still handles their width.
        window = [Signal(data.ArrayLayout(node_layout, h), name=f"window_{c}", reset_less=True) for c in range(span)]
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
        free_meta = Signal(data.ArrayLayout(meta_layout, t.term_stages), reset_less=True)
        free_valid = Signal(t.term_stages)
        m.d.sync += [free_meta[0].eq(sync_meta[t.step_stages - 1]), free_valid[0].eq(fresh)]
        for x in range(1, t.term_stages):
            m.d.sync += [free_meta[x].eq(free_meta[x - 1]), free_valid[x].eq(free_valid[x - 1])]

        # ---- the lanes ------------------------------------------------------------------------------
        lane_values = []
        for q in range(L):
            # Window sum of the valid nodes, on the columns as they arrive (step-synchronous). An
            # invalid node's depth register is held at zero by its synchronous reset: no LUT per bit.
            masked = Signal(data.ArrayLayout(depth, nodes), name=f"lane{q}_masked", reset_less=True)
            for k in range(h):
                for l in range(w):
                    x = k * w + l
                    with m.If(~patch_valid[x]):
                        m.d.sync += masked[x].eq(0)
                    with m.Elif(advance):
                        m.d.sync += masked[x].eq(window[top + q + l][k].depth)
            wsum = _pipelined_sum(m, advance, [masked[x] for x in range(nodes)], (widths.depth.lo, widths.depth.hi),
                                  (widths.window_sum.lo, widths.window_sum.hi), f"lane{q}_wsum")

            # The same columns, sum_levels + 1 steps later, at the bottom of the register: the terms, their
            # positive parts, their sum; the plain mode's correction (sum_valid M - sum_valid S) travels
            # beside them to the last stage.
            y = Signal(data.ArrayLayout(offset, nodes), name=f"lane{q}_y", reset_less=True)
            wsum_y = [Signal(window_sum_copy, name=f"lane{q}_wsum_y{c}", reset_less=True) for c in range(copies)]
            correction = Signal(data.ArrayLayout(difference_sum, t.term_stages - 1), name=f"lane{q}_correction",
                                reset_less=True)
            z = Signal(data.ArrayLayout(term, nodes), name=f"lane{q}_z", reset_less=True)
            positive = Signal(data.ArrayLayout(abs_term, nodes), name=f"lane{q}_positive", reset_less=True)
            m.d.sync += [
                correction[0].eq(Mux(mean_compensation, 0, wsum - patch_sum)),
            ]
            m.d.sync += [wsum_y[c].eq(Mux(mean_compensation, wsum + c, c)) for c in range(copies)]
            m.d.sync += [correction[x].eq(correction[x - 1]) for x in range(1, t.term_stages - 1)]
            for k in range(h):
                for l in range(w):
                    x = k * w + l
                    negative = z[x].as_unsigned()[-1]
                    m.d.sync += [
                        y[x].eq(window[q + l][k].scaled - centred_patch[x]),
                        z[x].eq(y[x] - wsum_y[x // copy_nodes]),
                        # A register's synchronous reset: one LUT per node, none per bit.
                        positive[x].eq(Mux(patch_valid[x] & ~negative, z[x], 0)),
                    ]
            positives = _pipelined_sum(m, None, [positive[x] for x in range(nodes)], (0, term_max),
                                       (0, widths.accumulator.hi), f"lane{q}_sum")
            value = Signal(unsigned(widths.accumulator.bits), name=f"lane{q}_value", reset_less=True)
            m.d.sync += value.eq((positives << 1) - correction[t.term_stages - 2])
            lane_values.append(value)

        # ---- into the output queue ---------------------------------------------------------------------
        last_meta = free_meta[t.term_stages - 1]
        last_valid = free_valid[t.term_stages - 1] & last_meta.live
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
        prepare_step = Signal(range(2 * nodes + 3))
        centre_copy = Signal(_index(copies))  # the copy of the window sum of the node being centred
        centre_run = Signal(_index(copy_nodes))  # ... and the node's place among that copy's nodes
        centring = Signal()  # the second pass shifts a node into ``centred_patch`` (cycles hw + 3 .. 2hw + 2)
        # The patch is read in place (not rotated), so a reset mid-pass leaves it intact; the memory's
        # read register, one after it (a block RAM's output is slow) and one after the multiplier keep
        # the passes' paths short.
        node = Signal(_index(nodes))
        with m.If(idle | (node == nodes - 1)):
            m.d.sync += node.eq(0)
        with m.Else():
            m.d.sync += node.eq(node + 1)
        head_read = Signal(depth)
        head_depth = Signal(depth)
        head_valid_read = Signal()
        head_valid = Signal()
        product = Signal(scaled)
        m.d.comb += [patch_read.addr.eq(node), head_read.eq(patch_read.data)]
        m.d.sync += [
            head_valid_read.eq(patch_valid.bit_select(node, 1)),
            head_depth.eq(head_read),
            head_valid.eq(head_valid_read),
            product.eq(factor * head_depth),
        ]
        # Outside the state machine, so that the register alone enables the shift.
        with m.If(centring):
            m.d.sync += [centred_patch[x].eq(centred_patch[x + 1]) for x in range(nodes - 1)]
            m.d.sync += centred_patch[nodes - 1].eq(product - Mux(mean_compensation, patch_sum, 0) - centre_copy)
            with m.If(centre_run == copy_nodes - 1):
                m.d.sync += [centre_run.eq(0), centre_copy.eq(centre_copy + 1)]
            with m.Else():
                m.d.sync += centre_run.eq(centre_run + 1)
        with m.FSM():
            with m.State("IDLE"):
                m.d.comb += idle.eq(1)
                with m.If(self.start.valid & self.start.ready):
                    m.d.sync += [
                        mean_compensation.eq(self.start.payload.mean_compensation),
                        valid_count.eq(0),
                        patch_sum.eq(0),
                        prepare_step.eq(0),
                        centre_copy.eq(0),
                        centre_run.eq(0),
                        patch_pointer.eq(0),
                        request_addr.eq(0),
                        flush_left.eq(t.flush_steps),
                        credits.eq(t.queue_depth),
                        step_row.eq(0),
                        step_group.eq(0),
                    ]
                    # The step-synchronous stages still hold the last correlation's flush steps.
                    m.d.sync += [sync_meta[x].live.eq(0) for x in range(t.step_stages)]
                    m.next = "COUNT"
            with m.State("COUNT"):
                # First pass: n and sum_valid S, from node k - 2 on cycle k = 2 .. hw + 1.
                m.d.sync += prepare_step.eq(prepare_step + 1)
                with m.If(prepare_step >= 2):
                    m.d.sync += [
                        valid_count.eq(valid_count + head_valid),
                        patch_sum.eq(patch_sum + Mux(head_valid, head_depth, 0)),
                    ]
                with m.If(prepare_step == nodes + 1):
                    m.d.sync += factor.eq(Mux(mean_compensation, valid_count + head_valid, 1))
                    m.next = "CENTRE"
            with m.State("CENTRE"):
                # Second pass: C = f * S - Ssum of node k - hw - 3 on cycle k = hw + 3 .. 2hw + 2,
                # shifted into the centred register so that it ends in node order.
                m.d.sync += prepare_step.eq(prepare_step + 1)
                # The shift's enable reaches every node's register: a register of its own.
                with m.If(prepare_step == nodes + 2):
                    m.d.sync += centring.eq(1)
                with m.If(prepare_step == 2 * nodes + 2):
                    m.d.sync += centring.eq(0)
                with m.If(prepare_step == 2 * nodes + 2):
                    m.d.sync += [running.eq(1), issuing.eq(1), issuing_words.eq(1)]
                    m.next = "RUN"
            with m.State("RUN"):
                with m.If(self.surface.valid & self.surface.ready & self.surface.payload.last):
                    m.d.sync += running.eq(0)
                    m.next = "IDLE"

        return m



class WindowCorrelator(wiring.Component):
    """The window correlator with its map memory, map loader and best-fit reducer.

    Throughput and latency, with ``surface.ready`` and ``best.ready`` high: one memory row (``L``
    words) and one beat of ``L`` placements per clock once the pipeline is full; a correlation takes
    ``2hw + 5 + H * ceil(W / L) + output_delay`` cycles to its last surface beat (one more when a
    row's last beat wraps to the next row's first step), then the reducer's pipeline and scan.
    Every beat's cycle is :func:`lost.model.cycles_window.schedule`;
    ``output_delay = 2 * ceil(log2(h * w)) + 7``.

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

    Members
    -------
    map_in, patch_in, start, surface, best, busy
        See :func:`lost.hdl.interface.correlator_signature`.

    Raises
    ------
    ValueError
        See :class:`lost.hdl.interface.CorrelatorParameters`.
    """

    def __init__(self, *, map_shape, patch_shape, depth_bits: int = 16, lanes: int = 1, exclusion_radius: int = 1):
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
        (H, W), L = p.map_shape, p.lanes

        m.submodules.core = core = WindowCore(
            map_shape=p.map_shape, patch_shape=p.patch_shape, depth_bits=p.depth_bits, lanes=L,
            exclusion_radius=p.exclusion_radius)
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
