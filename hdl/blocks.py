"""Pipeline blocks every core shares: delay lines (in registers or block RAM), an adder tree, a minimum tree, replicas.

Each block is a :class:`~amaranth.lib.wiring.Component` with a fixed latency, stated in its docstring
and checked against a NumPy model in ``tests/hdl/test_blocks.py`` (as maia-hdl does for every block).
Every register of a tree is on a level of its own, so that no path runs through more than one adder or
one comparison. None of them knows a device: a register meant to stay a separate copy is only *named*
``*_replica*``; keeping it apart through synthesis is the flow's choice (:mod:`lost.hdl.flow.synth`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from amaranth.hdl import Module, Mux, Shape, ShapeLike, Signal, Value, signed, unsigned
from amaranth.lib import data, memory, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import ceil_log2

from lost.model.widths import bits_for

__all__ = ["AdderTree", "DelayLine", "MemoryDelayLine", "MinimumTree", "ProductBlock", "RegisteredProduct", "Replicas",
           "check_count", "delayed", "enabled_delay", "index_range", "minimum_item", "shape_for", "tree_levels"]


def shape_for(lo: int, hi: int) -> Shape:
    """The narrowest shape holding every integer of ``[lo, hi]``: unsigned unless ``lo < 0``."""
    width, is_signed = bits_for(lo, hi)
    return signed(width) if is_signed else unsigned(width)


def index_range(count: int) -> range:
    """The range of an index below ``count``, at least one bit wide (Verilog has no empty vector)."""
    return range(max(count, 2))


def tree_levels(count: int) -> int:
    """Register levels of a binary tree over ``count`` leaves: ``ceil(log2(count))``, 0 for one leaf."""
    return ceil_log2(count)


def check_count(name: str, value: Any) -> int:
    """``value`` if it is a positive integer (not a bool), else a ``ValueError`` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return value


class DelayLine(wiring.Component):
    """``depth`` registers in a row: ``taps[k]`` is ``i`` as it was ``k + 1`` loads ago.

    Latency: ``depth`` loads from ``i`` to ``o`` (``o`` is ``taps[depth - 1]``); with ``depth = 0``,
    ``o`` is ``i`` itself. Without ``enable`` every clock loads.

    Parameters
    ----------
    shape : ShapeLike
        Of the value delayed (a layout too).
    depth : int
        Registers, at least 0.
    enable : bool
        Load only on clocks when ``en`` is high.
    reset_less : bool
        Registers without a reset (a datapath's: a reset would only add a net to each).

    Members
    -------
    i : ``In(shape)``
    en : ``In(1)``
        Only with ``enable``.
    taps : ``Out(ArrayLayout(shape, depth))``
        Every register, the newest first (absent when ``depth`` is 0).
    o : ``Out(shape)``
        The oldest.
    """

    def __init__(self, shape: ShapeLike, depth: int, *, enable: bool = False, reset_less: bool = False):
        if isinstance(depth, bool) or not isinstance(depth, int) or depth < 0:
            raise ValueError(f"depth must be a non-negative integer, got {depth!r}")
        self._shape, self._depth, self._enable, self._reset_less = shape, depth, bool(enable), bool(reset_less)
        members = {"i": In(shape), "o": Out(shape)}
        if depth:
            members["taps"] = Out(data.ArrayLayout(shape, depth))
        if enable:
            members["en"] = In(1)
        super().__init__(members)

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        value = self.i
        for stage in range(self._depth):
            register = Signal(self._shape, name=f"d{stage + 1}", reset_less=self._reset_less)
            load = register.eq(value)
            if self._enable:
                with m.If(self.en):
                    m.d.sync += load
            else:
                m.d.sync += load
            m.d.comb += self.taps[stage].eq(register)
            value = register
        m.d.comb += self.o.eq(value)
        return m


#: Data bits of one block RAM port (the ECP5's DP16KD: 18; two ports joined give 36).
BLOCK_RAM_PORT_BITS = 18


def delayed(m: Module, value: Value, shape: ShapeLike, cycles: int, name: str) -> Value:
    """``value`` through a :class:`DelayLine` of ``cycles`` registers, added to ``m`` as ``name``."""
    m.submodules[name] = line = DelayLine(shape, cycles)
    m.d.comb += line.i.eq(value)
    return line.o


class MemoryDelayLine(wiring.Component):
    """A delay of ``depth`` loads, as :class:`DelayLine` with ``enable`` and only ``o``, in block RAM.

    A long, wide delay that moves only when ``en`` is high costs a flip-flop per bit and stage as
    registers; here it is a memory written at a pointer that moves with the loads (on every clock: the
    entry's last write before the pointer moves is the load's) and read one load ahead into ``o``, a
    register: the entry ``o`` takes on a load was read on the load
    before, so a load on every clock is as exact as a load now and then, and no path runs from the
    block RAM to anything but ``o``. The entry read was written at least one load before it is read
    and the memory holds ``depth - 1`` or more entries, so the read port needs no transparency and
    never reads an entry being written. The memory asks synthesis for block RAM (``ram_style``), where
    a short memory would otherwise be made of LUTs, one of :data:`BLOCK_RAM_PORT_BITS` bits at a time.

    Latency: ``depth`` loads from ``i`` to ``o``, as :class:`DelayLine`: after load ``n``, ``o`` is
    ``i`` as it was on load ``n - depth + 1``. Before ``depth`` loads it is zero (the memory's and the
    register's initial value), as a :class:`DelayLine`'s registers after a reset; a later reset
    restarts nothing (there is none), so the delay holds across one.

    Parameters
    ----------
    shape : ShapeLike
        Of the value delayed (a layout too).
    depth : int
        Loads, at least 3 (a shorter delay is a register or two: :class:`DelayLine`).

    Members
    -------
    i : ``In(shape)``
    en : ``In(1)``
    o : ``Out(shape)``
    """

    def __init__(self, shape: ShapeLike, depth: int):
        if isinstance(depth, bool) or not isinstance(depth, int) or depth < 3:
            raise ValueError(f"depth must be an integer of at least 3, got {depth!r}")
        self._shape, self._depth = shape, depth
        #: Entries in the memory: a power of two of at least ``depth - 1``, so the pointers wrap by themselves.
        self.entries = 1 << ceil_log2(depth - 1)
        super().__init__({"i": In(shape), "en": In(1), "o": Out(shape)})

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        value = Value.cast(self.i)
        width = len(value)
        pointer = Signal(range(self.entries), name="pointer", reset_less=True)
        fetched = Signal(width, name="fetched", reset_less=True)
        output = Signal(self._shape, name="o_register", reset_less=True)
        # One memory per BLOCK_RAM_PORT_BITS bits: a block RAM's port of that width rather than both ports
        # joined into one of twice it (twice the blocks, half the data pins at each, which the 4-lane build's
        # router needs). ``no_rw_check``: the entry read is never the one being written, so Yosys need not
        # emulate a read-before-write across the two ports (a register and a multiplexer per bit); it
        # applies when Yosys merges a register into a read port, so the read is asynchronous here and
        # ``fetched`` is the register it merges (the block RAM's own output register). The entry at the
        # pointer is written on every clock, so its last write is the load's (nothing reads it before the
        # pointer moves on) and the step enable reaches no write-enable pin, only the read's clock enable.
        for low in range(0, width, BLOCK_RAM_PORT_BITS):
            piece = value[low:low + BLOCK_RAM_PORT_BITS]
            m.submodules[f"entries{low // BLOCK_RAM_PORT_BITS}"] = entries = memory.Memory(
                shape=len(piece), depth=self.entries, init=[], attrs={"ram_style": "block", "no_rw_check": 1})
            write, read = entries.write_port(), entries.read_port(domain="comb")
            # On load n the entry of load n - depth + 2 is fetched, for ``o`` to take on load n + 1.
            m.d.comb += [
                write.addr.eq(pointer),
                write.en.eq(1),
                write.data.eq(piece),
                read.addr.eq((pointer - (self._depth - 2))[:len(pointer)]),
            ]
            with m.If(self.en):
                m.d.sync += fetched[low:low + len(piece)].eq(read.data)
        with m.If(self.en):
            m.d.sync += [pointer.eq(pointer + 1), output.eq(fetched)]
        m.d.comb += self.o.eq(output)
        return m


#: The shortest delay :func:`enabled_delay` puts in block RAM: below it, the memory's two registers
#: and its pointer are not worth a block RAM.
MEMORY_DELAY_DEPTH = 8


def enabled_delay(shape: ShapeLike, depth: int) -> DelayLine | MemoryDelayLine:
    """A delay of ``depth`` loads (ports ``i``, ``en``, ``o``): in block RAM from :data:`MEMORY_DELAY_DEPTH` loads on.

    Either is exact (:class:`MemoryDelayLine`, :class:`DelayLine` with ``enable``, reset-less); the
    choice is only what it costs.
    """
    if depth >= MEMORY_DELAY_DEPTH:
        return MemoryDelayLine(shape, depth)
    return DelayLine(shape, depth, enable=True, reset_less=True)


class AdderTree(wiring.Component):
    """The sum of ``count`` leaves by a balanced adder tree, one register level per adder level.

    Latency: :func:`tree_levels` ``(count)`` loads (``ceil(log2(count))``); one leaf passes through.
    Pairs are summed in order (leaves 0 + 1, 2 + 3, ...; an odd last one is carried up alone).

    With ``adders_per_register = k > 1`` only every ``k``-th level and the last are registers (``k``
    adders in series between them, the widest levels, near the leaves, not registered): the latency
    is the same, the levels' missing registers added after the root, where the sum is narrowest.

    With ``registered_sum=False`` the tree's last register (the last one made up after the root, or
    the root's level if there is none) is left to the consumer, one clock less: for a consumer whose
    register is not the fabric's, such as a multiplier's input register (:class:`RegisteredProduct`).

    Each level's registers are as wide as the sums they can hold: ``k`` leaves in ``[leaf_lo,
    leaf_hi]`` give ``[k * leaf_lo, k * leaf_hi]``, never more than ``total`` (the bounds of the whole
    sum, e.g. over the valid nodes only). The registers are reset-less (datapath registers).

    Parameters
    ----------
    count : int
        Leaves.
    leaf : (int, int)
        ``(lo, hi)`` of one leaf; the leaves' shape is :func:`shape_for` of it.
    total : (int, int)
        ``(lo, hi)`` of the sum.
    enable : bool
        Load only on clocks when ``en`` is high.
    adders_per_register : int
        Adder levels between two register levels (1: a register on every level).
    registered_sum : bool
        Whether ``sum`` is a register (the default) or the value its last register would load.

    Members
    -------
    leaves : ``In(ArrayLayout(shape_for(*leaf), count))``
    en : ``In(1)``
        Only with ``enable``.
    sum : ``Out(shape)``
        As wide as the last level (the leaf's shape for one leaf).
    """

    def __init__(self, *, count: int, leaf: tuple[int, int], total: tuple[int, int], enable: bool = False,
                 adders_per_register: int = 1, registered_sum: bool = True):
        self._count = check_count("count", count)
        if not registered_sum and count < 2:
            raise ValueError(f"a tree of {count} leaf has no register to leave out (registered_sum=False)")
        self._registered_sum = bool(registered_sum)
        self._adders_per_register = check_count("adders_per_register", adders_per_register)
        self._leaf, self._total, self._enable = tuple(leaf), tuple(total), bool(enable)
        self.leaf_shape = shape_for(*self._leaf)
        self.level_shapes = []
        leaves, values = 1, count
        while values > 1:
            leaves *= 2
            values = (values + 1) // 2
            self.level_shapes.append(shape_for(max(leaves * self._leaf[0], self._total[0]),
                                               min(leaves * self._leaf[1], self._total[1])))
        members = {
            "leaves": In(data.ArrayLayout(self.leaf_shape, count)),
            "sum": Out(self.level_shapes[-1] if self.level_shapes else self.leaf_shape),
        }
        if enable:
            members["en"] = In(1)
        super().__init__(members)

    @property
    def latency(self) -> int:
        return len(self.level_shapes) - (not self._registered_sum)

    @property
    def registered_levels(self) -> list[bool]:
        """For each level, the first (leaves' sums) first: whether it is a register."""
        levels, every = len(self.level_shapes), self._adders_per_register
        registered = [(level + 1) % every == 0 or level + 1 == levels for level in range(levels)]
        if not self._registered_sum and all(registered):
            registered[-1] = False  # no register made up after the root to leave out: the root's own
        return registered

    @property
    def _registers_after_root(self) -> int:
        """The levels' missing registers, made up after the root (but the one left to the consumer)."""
        missing = self.registered_levels.count(False)
        return missing - (not self._registered_sum)

    def elaborate(self, platform: Any) -> Module:
        m = Module()

        def load(assignments: list) -> None:
            if self._enable:
                with m.If(self.en):
                    m.d.sync += assignments
            else:
                m.d.sync += assignments

        values = [self.leaves[k] for k in range(self._count)]
        for level, (shape, registered) in enumerate(zip(self.level_shapes, self.registered_levels)):
            # One array signal per level (fewer, wider signals keep the generated Verilog small).
            # An unregistered level is ``keep``: else Yosys (``alumacc``) merges the adders on each side of
            # it into multi-operand sums, carry-save trees of LUTs (a 100-leaf tree of 17 bits: 2,619 LUT4
            # and 352 carry cells, against 66 and 955), where each adder should be a carry chain of its own.
            sums = Signal(data.ArrayLayout(shape, (len(values) + 1) // 2), name=f"l{level}", reset_less=True,
                          attrs={} if registered else {"keep": 1})
            pairs = [values[k] + values[k + 1] if k + 1 < len(values) else values[k] for k in range(0, len(values), 2)]
            assignments = [sums[k].eq(pair) for k, pair in enumerate(pairs)]
            if registered:
                load(assignments)
            else:
                m.d.comb += assignments
            values = [sums[k] for k in range((len(values) + 1) // 2)]
        root = values[0]
        # The levels without a register, made up after the root.
        for extra in range(self._registers_after_root):
            register = Signal(root.shape(), name=f"root{extra + 1}", reset_less=True)
            load([register.eq(root)])
            root = register
        m.d.comb += self.sum.eq(root)
        return m


def minimum_item(key: ShapeLike, payload: ShapeLike | None = None) -> data.StructLayout:
    """An item of a :class:`MinimumTree`: ``valid``, ``key`` and, if given, a ``payload`` carried along."""
    fields = {"valid": 1, "key": key}
    if payload is not None:
        fields["payload"] = payload
    return data.StructLayout(fields)


class MinimumTree(wiring.Component):
    """The valid leaf with the smallest key, by a compare tree with one register per level.

    Pairs are compared in order (leaves 0 with 1, 2 with 3, ...), the later one winning only with a
    strictly smaller key or when the earlier one is not valid: of equal keys the lowest leaf wins. The
    root is valid when any leaf is; its key and payload are then the winner's (dls_cores'
    ``dlsc_min_tree``, which carries the index, is the shape). With no valid leaf, the root's key and
    payload are those of some leaf and mean nothing.

    Latency: :func:`tree_levels` ``(count)`` clocks; one leaf passes through. The registers have a
    reset (an invalid root after a reset).

    Parameters
    ----------
    count : int
        Leaves.
    key : ShapeLike
        Compared as its shape says (unsigned or signed).
    payload : ShapeLike or None
        Carried with the key (a column, an index).

    Members
    -------
    leaves : ``In(ArrayLayout(minimum_item(key, payload), count))``
    root : ``Out(minimum_item(key, payload))``
    """

    def __init__(self, *, count: int, key: ShapeLike, payload: ShapeLike | None = None):
        self._count = check_count("count", count)
        self.item = minimum_item(key, payload)
        super().__init__({
            "leaves": In(data.ArrayLayout(self.item, count)),
            "root": Out(self.item),
        })

    @property
    def latency(self) -> int:
        return tree_levels(self._count)

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        level = [self.leaves[k] for k in range(self._count)]
        depth = 0
        while len(level) > 1:
            depth += 1
            merged = []
            for k in range(0, len(level), 2):
                register = Signal(self.item, name=f"l{depth}_{k // 2}")
                if k + 1 < len(level):
                    first, second = level[k], level[k + 1]
                    take = second.valid & (~first.valid | (second.key < first.key))
                    m.d.sync += [
                        register.valid.eq(first.valid | second.valid),
                        register.key.eq(Mux(take, second.key, first.key)),
                    ]
                    if "payload" in self.item.members:
                        m.d.sync += register.payload.eq(Mux(take, second.payload, first.payload))
                else:
                    m.d.sync += register.eq(level[k])
                merged.append(register)
            level = merged
        m.d.comb += self.root.eq(level[0])
        return m


class Replicas(wiring.Component):
    """``count`` registers all loaded from ``i``: copies of one slow-changing value near their loads.

    A value that reaches much of a design (a mode bit, a divisor) has a fan-out no one register
    drives fast; each part takes its own copy. The registers are named ``copy<k>_replica`` so that the
    synthesis flow can keep them apart (Yosys would merge equal registers); the gateware itself marks
    nothing device-specific.

    Latency: 1 clock. The registers have a reset (to ``init``).

    Parameters
    ----------
    shape : ShapeLike
    count : int
    init : int
        The registers' reset value.

    Members
    -------
    i : ``In(shape)``
    o : ``Out(ArrayLayout(shape, count))``
    """

    def __init__(self, shape: ShapeLike, count: int, *, init: int = 0):
        self._shape, self._count, self._init = shape, check_count("count", count), init
        super().__init__({"i": In(shape), "o": Out(data.ArrayLayout(shape, count))})

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        for k in range(self._count):
            register = Signal(self._shape, name=f"copy{k}_replica", init=self._init)
            m.d.sync += register.eq(self.i)
            m.d.comb += self.o[k].eq(register)
        return m


class RegisteredProduct(wiring.Component):
    """``a * b`` of unsigned operands registered on their way in: a multiplier holding its own input registers.

    A device's multiplier block may hold its operands' registers inside it (the ECP5's ``MULT18X18D``
    does); a product of fabric registers pays a route into the block and one out of it on one path.
    This block is the generic form, two registers and their product; a builder for a device may give a
    block of its own with the same members and timing (the cores' ``product`` option,
    :class:`lost.hdl.flow.harness.ECP5RegisteredProduct`).

    Latency: 1 clock to the operands' registers (reset-less); ``p`` follows them combinationally.

    Parameters
    ----------
    a_bits, b_bits : int
        The operands' widths.

    Members
    -------
    a : ``In(unsigned(a_bits))``
    b : ``In(unsigned(b_bits))``
    p : ``Out(unsigned(a_bits + b_bits))``
    """

    def __init__(self, a_bits: int, b_bits: int):
        self.a_bits, self.b_bits = check_count("a_bits", a_bits), check_count("b_bits", b_bits)
        super().__init__({"a": In(unsigned(a_bits)), "b": In(unsigned(b_bits)), "p": Out(unsigned(a_bits + b_bits))})

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        a = Signal(unsigned(self.a_bits), name="a_register", reset_less=True)
        b = Signal(unsigned(self.b_bits), name="b_register", reset_less=True)
        m.d.sync += [a.eq(self.a), b.eq(self.b)]
        m.d.comb += self.p.eq(a * b)
        return m


#: How a core makes a :class:`RegisteredProduct`: ``(a_bits, b_bits) -> component`` of its members and timing.
ProductBlock = Callable[[int, int], wiring.Component]
