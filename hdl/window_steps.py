"""The window correlator's steps: when each is issued, and the beat each completes.

A *step* takes one memory row of ``L`` map words or, after the last, one of a fixed number of flush
steps without a word (:mod:`lost.model.cycles_window`). :class:`StepIssue` issues them against the
output queue's credits and the map sequencer's readiness, and holds the step enable ``advance``;
:class:`BeatMetadata` knows from the count of steps taken which surface beat each step completes and
carries it beside the pipeline's stages, so that it reaches the output queue with the lanes' values.
"""

from __future__ import annotations

from typing import Any

from amaranth.hdl import Const, Module, Mux, Signal, Value, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import ceil_log2

from lost.hdl.blocks import DelayLine, check_count, index_range
from lost.hdl.interface import CorrelatorParameters, checked_parameters
from lost.hdl.window_lane import PipelineStages
from lost.model.cycles_window import window_timing

__all__ = ["BeatMetadata", "StepIssue", "beat_layout"]



class StepIssue(wiring.Component):
    """A correlation's steps, ``words`` map reads then ``flush_steps`` flush steps, each against a credit.

    ``begin`` sets a run going; its steps are then issued in order, at most one a cycle: in a cycle in
    which ``has_credit`` is high and, for a map word, the request for it transfers (``request`` carries
    the addresses ``0 .. words - 1``; its ``valid`` does not wait for ``request.ready``, which is the
    map sequencer's register). After the last flush step nothing issues until the next ``begin``.
    ``clear`` puts the counters back to the first step (address 0, every flush step left); it does not
    stop a run, so each run is cleared before its ``begin`` (the core clears while idle; a reset stops
    a run), or on the same edge: ``clear`` with ``begin`` restarts a run from its first step. Both take
    precedence over a step issued on their edge.

    Latency: ``issue`` is combinational, high in a cycle in which a step is issued, i.e. on the edge
    ending it. ``advance`` and ``step_is_word`` are registers, high in the cycle after an issue: the
    stages that load on ``advance`` take the step on the edge after the one it was issued on (the
    cycle model's count: issued on edge ``e``, taken on edge ``e + 1``). After a ``begin`` sampled on
    edge ``e``, the first step can issue in the cycle ending on edge ``e + 1``. ``clear`` counts from
    the edge it is sampled on.

    ``advance`` is the one enable of every step-synchronous stage; it leaves here as a register's net,
    which the core's builder may carry to its loads (``enable_buffer``).

    Parameters
    ----------
    words : int
        Map words (memory rows) read per correlation.
    flush_steps : int
        Steps without a word after them (:attr:`~lost.model.cycles_window.WindowTiming.flush_steps`).

    Members
    -------
    request : ``Out(stream.Signature(unsigned(ceil_log2(words))))``
        The map reads, by memory row.
    has_credit : ``In(1)``
        The output queue holds a credit.
    issue : ``Out(1)``
        A step is issued (it takes a credit).
    advance : ``Out(1)``
        A step is taken on this cycle's edge: the step enable.
    step_is_word : ``Out(1)``
        The step taken is a map word (with ``advance``; a flush step's ``advance`` has it low).
    begin : ``In(1)``
        Start issuing a run's steps (the patch pass is done).
    clear : ``In(1)``
        Back to the first step.
    """

    def __init__(self, *, words: int, flush_steps: int):
        self._words = check_count("words", words)
        self._flush_steps = check_count("flush_steps", flush_steps)
        super().__init__({
            "request": Out(stream.Signature(unsigned(ceil_log2(words)))),
            "has_credit": In(1),
            "issue": Out(1),
            "advance": Out(1),
            "step_is_word": Out(1),
            "begin": In(1),
            "clear": In(1),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        issuing = Signal()  # steps of this run are left to issue
        issuing_words = Signal()  # ... and map words among them
        request_addr = Signal(range(self._words + 1))
        flush_left = Signal(range(self._flush_steps + 1))
        m.d.comb += [
            self.issue.eq(issuing & self.has_credit & (self.request.ready | ~issuing_words)),
            self.request.valid.eq(issuing & issuing_words & self.has_credit),
            self.request.payload.eq(request_addr),
        ]
        with m.If(self.issue):
            with m.If(issuing_words):
                m.d.sync += request_addr.eq(request_addr + 1)
                with m.If(request_addr == self._words - 1):
                    m.d.sync += issuing_words.eq(0)
            with m.Else():
                m.d.sync += flush_left.eq(flush_left - 1)
                with m.If(flush_left == 1):
                    m.d.sync += issuing.eq(0)
        with m.If(self.clear):
            m.d.sync += [request_addr.eq(0), flush_left.eq(self._flush_steps)]
        with m.If(self.begin):
            m.d.sync += [issuing.eq(1), issuing_words.eq(1)]

        # A register: the step-synchronous stages' enable starts at no logic.
        advance = Signal()
        step_is_word = Signal()
        m.d.sync += [advance.eq(self.issue), step_is_word.eq(self.issue & issuing_words)]
        m.d.comb += [self.advance.eq(advance), self.step_is_word.eq(step_is_word)]
        return m


def beat_layout(parameters: CorrelatorParameters) -> data.StructLayout:
    """What :class:`BeatMetadata` says of a step's beat.

    ``live``: a step taken since the last clear (not a stage's cleared content); ``emit``: the step
    completes a surface beat, ``(i, j)`` its first placement, ``count`` its placements, ``last`` the
    correlation's last beat (the four are meaningless without ``emit``).
    """
    p = parameters
    return data.StructLayout({
        "live": 1, "emit": 1, "i": unsigned(p.row_bits), "j": unsigned(p.col_bits),
        "count": p.surface_beat["count"].shape, "last": 1,
    })


class BeatMetadata(wiring.Component):
    """The beat each step completes, and the group it reads, carried beside the pipeline's stages.

    Steps are counted from the last ``clear``: step ``s`` is the memory row ``divmod(s, G)`` (map row,
    group), a flush step from map row ``H`` on. It completes the surface beat ``(i, g)`` whose step
    :func:`lost.model.cycles_window.completing_steps` gives (``i = r - h + 1`` and ``g = group - D``
    within a row, the next row's first step for a row's last beat that wraps).

    The beat is formed in two step-synchronous stages from counters one step ahead (formed from the
    step's row and group in one clock, it is 14 logic cells deep: the critical path of badd2e3's 3 lanes): its
    parts (whether the step completes a beat in its row or wraps, the beat's row and group, whether each
    is the last) load on the step before, the beat from them on the step itself. It then moves with the
    step through the ``quotient`` step-synchronous stages (:class:`~lost.hdl.window_lane.PipelineStages`)
    and the ``value`` term stages, which run on every clock: ``fresh`` marks the clocks on which the
    last edge was a step, when the lanes' values are a new placement's (otherwise they recompute the
    previous one, and the beat is stale).

    Latency: let step ``s`` be taken on edge ``e_s`` (``advance`` high in the cycle ending on it).
    ``group`` is step ``s``'s group in every cycle from the one after ``e_{s-1}`` (after the clear's
    edge, for step 0) to the one ending on ``e_s``. ``fresh`` is high in the cycle after edge
    ``e_s + value`` (``value`` clocks after ``e_s``) for each step ``s``, low in every other; ``beat``
    then holds step ``s - quotient + 1``'s beat (``beat`` means nothing without ``fresh``). So step
    ``s``'s beat leaves ``value`` clocks after the edge taking the ``quotient - 1``-th step after it:
    ``output_delay - 1`` edges after ``e_s`` when steps follow one a clock, and it is written into the
    queue on edge ``e_s + output_delay``, as :mod:`lost.model.cycles_window` counts. When step
    ``s - quotient + 1`` would precede the last clear (``s`` is among the first ``quotient - 1`` steps
    after it), ``beat`` is a stage's cleared content: ``live`` low.

    Parameters
    ----------
    parameters : CorrelatorParameters

    Members
    -------
    advance : ``In(1)``
        The step enable.
    clear : ``In(1)``
        The next step is step 0: the counters go back to it and the step-synchronous stages' beats
        lose ``live`` (they may hold the last run's flush steps). Takes precedence over ``advance``.
    group : ``Out(range(G))``
        The group (memory row within its map row) of the step being taken: the line buffers' write address.
    next_group : ``Out(range(G))``
        ``(group + 1) mod G``, the group of the step after it, in every cycle:
        the line buffers' read address, a register (formed from ``group`` by an adder and a compare on its
        way to 36 block RAMs, it is the critical path of 063d056's 4-lane build).
    beat : ``Out(beat_layout(parameters))``
        The beat of the step at the value stage.
    fresh : ``Out(1)``
        ``beat`` is a step's that the last term edge carried, not a stale repeat.
    write, passed : ``Out(1)``
        ``fresh & beat.live & beat.emit`` and ``fresh & beat.live & ~beat.emit`` (the beat goes to the queue,
        or its step passes without one), each a register equal to its expression on every cycle.
    write_next : ``Out(1)``
        The value ``write`` takes on the next edge.

    Attributes
    ----------
    layout : StructLayout
        :func:`beat_layout`.
    stages : PipelineStages
    """

    def __init__(self, *, parameters: CorrelatorParameters):
        checked_parameters(parameters)
        self._parameters = p = parameters
        self._timing = window_timing(p.map_shape, p.patch_shape, p.lanes)
        self.stages = PipelineStages.of(self._timing)
        self.layout = beat_layout(p)
        super().__init__({
            "advance": In(1),
            "clear": In(1),
            "group": Out(index_range(self._timing.groups)),
            "next_group": Out(index_range(self._timing.groups)),
            "beat": Out(self.layout),
            "fresh": Out(1),
            "write": Out(1),
            "write_next": Out(1),
            "passed": Out(1),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        step_beat = self._step_beat(m)
        stages = self.stages
        sync_beats = Signal(data.ArrayLayout(self.layout, stages.quotient), reset_less=True)
        with m.If(self.advance):
            m.d.sync += sync_beats[0].eq(step_beat)
            m.d.sync += [sync_beats[x].eq(sync_beats[x - 1]) for x in range(1, stages.quotient)]
        with m.If(self.clear):
            m.d.sync += [sync_beats[x].live.eq(0) for x in range(stages.quotient)]
        # Only the valid bits need a reset: after one, no stale step may reach the queue.
        fresh = Signal()
        m.d.sync += fresh.eq(self.advance)
        m.submodules.term_meta = term_meta = DelayLine(self.layout, stages.value, reset_less=True)
        m.submodules.term_valid = term_valid = DelayLine(1, stages.value)
        m.d.comb += [
            term_meta.i.eq(sync_beats[stages.quotient - 1]),
            term_valid.i.eq(fresh),
            self.beat.eq(term_meta.o),
            self.fresh.eq(term_valid.o),
        ]
        # The queue's write and a step's passing, as registers loaded from the stage before the last (value >= 3):
        # each equals its expression of fresh and beat on every cycle, and the write's next value lets the
        # queue keep copies of it near its storage.
        before_meta, before_valid = term_meta.taps[stages.value - 2], term_valid.taps[stages.value - 2]
        write, passed = Signal(), Signal()
        m.d.comb += self.write_next.eq(before_valid & before_meta.live & before_meta.emit)
        m.d.sync += [write.eq(self.write_next), passed.eq(before_valid & before_meta.live & ~before_meta.emit)]
        m.d.comb += [self.write.eq(write), self.passed.eq(passed)]
        return m

    def _parts_of(self, row: Value, group: Value) -> list:
        """The beat of the step at ``row``, ``group``, as assignments to a ``parts`` value's fields."""
        p, t = self._parameters, self._timing
        H, h = p.map_shape[0], p.patch_shape[0]
        normal = (row >= h - 1) & (row <= H - 1) & (group >= t.lead)
        return [
            ("normal", normal),
            ("wrapped", Const(t.wraps) & (group == 0) & (row >= h) & (row <= H)),
            ("row", Mux(normal, row - (h - 1), row - h)),
            ("group", Mux(normal, group - t.lead, t.out_groups - 1)),
            # The beat's row is Ho - 1 (its group out_groups - 1) without forming it first.
            ("last_row", Mux(normal, row == H - 1, row == H)),
            ("last_group", ~normal | (group == t.out_groups - 1 + t.lead)),
        ]

    def _step_beat(self, m: Module) -> Signal:
        """The beat of the step being taken, from ``parts`` loaded on the step before; drives ``group`` and
        ``next_group``."""
        p, t = self._parameters, self._timing
        H, L, G = p.map_shape[0], p.lanes, t.groups
        Wo = p.surface_shape[1]
        parts_layout = data.StructLayout({
            "normal": 1, "wrapped": 1, "row": unsigned(p.row_bits), "group": index_range(t.out_groups),
            "last_row": 1, "last_group": 1,
        })
        step_group = Signal(index_range(G))
        ahead_row = Signal(range(H + t.flush_steps + 3))
        second_group, second_row = (1, 0) if G > 1 else (0, 1)  # the second step's group and row
        ahead_group = Signal(index_range(G), init=second_group)  # (step_group + 1) mod G from the reset on
        parts = Signal(parts_layout)
        with m.If(self.advance):
            m.d.sync += [step_group.eq(ahead_group),
                         *(parts[name].eq(value) for name, value in self._parts_of(ahead_row, ahead_group))]
            with m.If(ahead_group == G - 1):
                m.d.sync += [ahead_group.eq(0), ahead_row.eq(ahead_row + 1)]
            with m.Else():
                m.d.sync += ahead_group.eq(ahead_group + 1)
        with m.If(self.clear):
            m.d.sync += [step_group.eq(0), ahead_group.eq(second_group), ahead_row.eq(second_row),
                         *(parts[name].eq(value) for name, value in self._parts_of(Const(0, 1), Const(0, 1)))]
        m.d.comb += [self.group.eq(step_group), self.next_group.eq(ahead_group)]
        step_beat = Signal(self.layout)
        m.d.comb += [
            step_beat.live.eq(1),
            step_beat.emit.eq(parts.normal | parts.wrapped),
            step_beat.i.eq(parts.row),
            step_beat.j.eq(parts.group * L),
            step_beat.count.eq(Mux(parts.last_group, Wo - (t.out_groups - 1) * L, L)),
            step_beat.last.eq(parts.last_row & parts.last_group),
        ]
        return step_beat
