"""The window correlator's step register, line buffers and window register: map rows in, columns out."""

from __future__ import annotations

from typing import Any

from amaranth.hdl import Module, Signal, Value, signed
from amaranth.lib import data, memory, wiring
from amaranth.lib.wiring import In, Out

from lost.hdl.blocks import MemoryDelayLine, index_range

__all__ = ["StepWindow"]


class StepWindow(wiring.Component):
    """Memory rows of ``L`` map words in raster order, one per step; ``span`` window columns out.

    Step-synchronous (every register loads on ``advance`` only; no stream fits: the window follows
    the step enable). ``h - 1`` line buffers, each a delay of ``G = ceil(W / L)`` steps, hold the map
    rows above the one being taken; each step the window register moves ``L`` columns to the left and
    takes ``L`` new columns of ``h`` words on the right (the word of the step register at the bottom).

    Latency: the words taken by step ``s`` (``word``, ``group`` and ``is_word`` sampled on edge
    ``e_s``) are in the step register after ``e_s``, and in ``columns[span - L + lane]`` (the bottom
    row of each) after ``e_{s+1}``; ``L`` columns further left after each later step. A map row's word
    is in the column's row ``h - 1 - k`` after ``k * G`` more steps (through the line buffers).

    A line buffer is a block RAM when ``G >= 3``: it is read one step ahead (the next step's group)
    into a register that loads with the step, and the next buffer is written from that register, so
    no path runs from one block RAM to another; the entry read was written at least one step before,
    so the read port needs no transparency. A delay of one or two steps is a register or two.

    The columns of the steps in ``stored`` (steps of ``L`` columns counted from the oldest: columns
    ``stored.start * L`` up to ``stored.stop * L``) are read by nothing but the columns below them, so
    they need not be registers: they are a :class:`~lost.hdl.blocks.MemoryDelayLine` of block RAM,
    written from the step at ``stored.stop`` and read into the step at ``stored.start - 1``, whose
    registers are the delay line's output. The window moves as if they were registers; only they are
    not among ``columns``.

    Parameters
    ----------
    lanes : int
        ``L``, words per step.
    rows : int
        ``h``, the patch's rows: words per column.
    groups : int
        ``G``, steps per map row.
    span : int
        Columns held.
    depth_bits : int
    stored : range
        Steps of the window held in block RAM (empty: none); at least two, above the first step and
        below the last: ``1 <= start``, ``start + 2 <= stop < span // L``.

    Members
    -------
    advance : ``In(1)``
        The step enable.
    word : ``In(ArrayLayout(signed(depth_bits), lanes))``
        The step's memory row (its content is ignored for a flush step).
    group : ``In(range(groups))``
        The group (memory row within its map row) of the step being taken.
    next_group : ``In(range(groups))``
        ``(group + 1) mod groups``, the next step's group: the line buffers' read address (the builder's
        register, :class:`~lost.hdl.window_steps.BeatMetadata`, so no adder lies before the block RAMs).
    is_word : ``In(1)``
        The step carries a map word (a flush step does not enter the line buffers).
    columns : ``Out(ArrayLayout(signed(depth_bits), rows)).array(span - len(stored) * lanes)``
        Oldest first, without the stored ones: port ``c`` is the window's column ``c`` below
        ``stored.start * L`` and its column ``c + len(stored) * L`` from there on; row ``h - 1`` of a
        column is the newest map row.
    """

    def __init__(self, *, lanes: int, rows: int, groups: int, span: int, depth_bits: int, stored: range = range(0)):
        for name, value in (("lanes", lanes), ("rows", rows), ("groups", groups), ("span", span)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"{name} must be a positive integer, got {value!r}")
        if span < lanes:
            raise ValueError(f"span must hold at least one step's {lanes} columns, got {span}")
        if not isinstance(stored, range) or stored.step != 1 or (
                len(stored) and not 1 <= stored.start <= stored.stop - 2 < span // lanes - 2):
            raise ValueError(f"stored must be a range of at least two steps, above the first and below the last "
                             f"of the window's {span // lanes}, got {stored!r}")
        self._lanes, self._rows, self._groups, self._span = lanes, rows, groups, span
        self._stored = range(stored.start * lanes, stored.stop * lanes) if len(stored) else range(0)
        self._stored_steps = stored
        self._depth = signed(depth_bits)
        self.row_layout = data.ArrayLayout(self._depth, lanes)
        super().__init__({
            "advance": In(1),
            "word": In(self.row_layout),
            "group": In(index_range(groups)),
            "next_group": In(index_range(groups)),
            "is_word": In(1),
            # One signal per column (an array of ports, not one wide port): the Python simulator spells a
            # signal's mask as a decimal literal, which a span of 10-row columns would make too long.
            "columns": Out(data.ArrayLayout(self._depth, rows)).array(span - len(self._stored)),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        advance, row_layout = self.advance, self.row_layout

        # The step register: the words and the group they were read for.
        step_nodes = Signal(row_layout, reset_less=True)
        step_group = Signal(index_range(self._groups))
        step_was_word = Signal()
        with m.If(advance):
            m.d.sync += [step_group.eq(self.group), step_was_word.eq(self.is_word), step_nodes.eq(self.word)]

        buffer_rows = self._line_buffers(m, step_nodes, step_group, step_was_word)
        window = self._window(m, buffer_rows, step_nodes)
        kept = [column for column in window if column is not None]
        m.d.comb += [self.columns[c].eq(kept[c]) for c in range(len(kept))]
        return m

    def _line_buffers(self, m: Module, step_nodes: Signal, step_group: Signal, step_was_word: Signal) -> list[Signal]:
        """Rows r-1 .. r-h+1 of the group being taken: one line buffer a row, its output register last."""
        h, G, row_layout, advance = self._rows, self._groups, self.row_layout, self.advance
        buffer_rows = []
        for x in range(h - 1):
            entering = step_nodes if x == 0 else buffer_rows[x - 1]
            registers = G if G <= 2 else 1
            delayed = [Signal(row_layout, name=f"line_buffer_{x}_out{y}", reset_less=True) for y in range(registers)]
            if G <= 2:
                with m.If(advance):
                    m.d.sync += [delayed[y].eq(delayed[y - 1] if y else entering) for y in range(G)]
            else:
                # The entry read (the next step's group) is never the one written (the last step's), so
                # Yosys need not emulate a read-before-write between the ports (``no_rw_check``, which it
                # applies to a register it merges into an asynchronous read: ``fetched``, as
                # :class:`~lost.hdl.blocks.MemoryDelayLine` does).
                m.submodules[f"line_buffer_{x}"] = line = memory.Memory(shape=row_layout, depth=G, init=[],
                                                                        attrs={"no_rw_check": 1})
                write = line.write_port()
                read = line.read_port(domain="comb")
                fetched = Signal(row_layout, name=f"line_buffer_{x}_fetched", reset_less=True)
                m.d.comb += [
                    read.addr.eq(self.next_group),
                    write.addr.eq(step_group),
                    write.en.eq(advance & step_was_word),
                    write.data.eq(entering),
                ]
                with m.If(advance):
                    m.d.sync += [fetched.eq(read.data), delayed[0].eq(fetched)]
            buffer_rows.append(delayed[-1])

        return buffer_rows

    def _window(self, m: Module, buffer_rows: list[Signal], step_nodes: Signal) -> list[Value | None]:
        """The window register, one signal a column (the stored steps' columns read from their block RAM);
        each step shifts it by ``lanes`` columns and enters the step's columns from the line buffers."""
        L, h, span, advance = self._lanes, self._rows, self._span, self.advance
        # The window register: one signal per column (fewer signals than one per node, while the Python
        # simulator, whose generated code spells masks as decimal literals, still handles their width).
        column_layout = data.ArrayLayout(self._depth, h)
        stored = self._stored
        window = [None if c in stored else Signal(column_layout, name=f"window_{c}", reset_less=True)
                  for c in range(span)]
        if stored:
            # The stored steps and the one below them: a delay from the step above them, in block RAM.
            below = range(stored.start - L, stored.start)
            m.submodules.stored = delay = MemoryDelayLine(data.ArrayLayout(column_layout, L),
                                                          len(self._stored_steps) + 1)
            m.d.comb += [delay.en.eq(advance), *(delay.i[q].eq(window[stored.stop + q]) for q in range(L))]
            for q, c in enumerate(below):
                window[c] = delay.o[q]
        else:
            below = range(0)
        with m.If(advance):
            for c in range(span - L):
                if c not in stored and c not in below:
                    m.d.sync += window[c].eq(window[c + L])
            for q in range(L):
                column = [buffer_rows[h - 2 - k][q] for k in range(h - 1)] + [step_nodes[q]]
                for k in range(h):
                    m.d.sync += window[span - L + q][k].eq(column[k])
        return window
