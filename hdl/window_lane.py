"""One lane of the window correlator: a placement's value from its window, by threshold terms.

The arithmetic (see :mod:`lost.hdl.window` for its derivation): with the lifted differences
``d' = M + (2**b - S)`` at the valid nodes, the dividend ``N`` (the window sum less ``Ssum`` plus
``f * 2**b``) and the quotient ``q = floor(N / f)``::

    V = 2 * (f * P' - K * N) - correction      P' = sum of the d' above q,  K = their count

The lane has two halves. The *step-synchronous* half loads only on ``advance`` (a step taken): the
masked depths of the window at the top of the window register, their sum tree, the dividend and the
quotient stages (:class:`~lost.hdl.window.PipelineStages` ``masked`` to ``quotient``). The *term* half
runs on every clock from the window at the bottom of the register (the same columns, ``quotient -
window`` steps later), which between steps recomputes the last placement.

``f`` holds still through a correlation, so the quotient is not a division per placement: each lane
forms ``m = ceil(2**s / f)`` once, serially (:class:`~lost.hdl.reciprocal.SerialReciprocal`), and ``q = floor(N * m / 2**s)``
is a product on the device's multipliers (:func:`~lost.hdl.reciprocal.reciprocal_quotient`), exact for every dividend the
lane can see (:func:`~lost.hdl.reciprocal.reciprocal_shift` proves the bound).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from amaranth.hdl import Cat, Const, Module, Mux, Shape, Signal, signed, unsigned
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import ceil_log2

from lost.hdl.blocks import AdderTree, ProductBlock, RegisteredProduct, Replicas, enabled_delay, shape_for
from lost.hdl.interface import CorrelatorParameters, checked_parameters
from lost.hdl.reciprocal import (
    SerialReciprocal,
    partial_pieces,
    reciprocal_product_stages,
    reciprocal_quotient,
    reciprocal_shift,
    weighted_sum,
)
from lost.model.cycles_window import QUOTIENT_STAGES, WindowTiming, window_timing

__all__ = [
    "LaneArithmetic",
    "PipelineStages",
    "TREE_ADDERS_PER_REGISTER",
    "WindowLane",
]

#: Adder levels between two registers in the lane's three 100-leaf trees (the window sum, the selected
#: differences' sum and their count): two adders of up to 24 bits in series stayed off the 1-lane build's
#: worst paths, and each tree keeps its latency (the registers it leaves out are added at its narrow
#: root); a lane holds about 1,100 fewer flip-flops in each sum tree. :class:`~lost.hdl.blocks.AdderTree`.
TREE_ADDERS_PER_REGISTER = 2

#: Consecutive nodes that share a copy of the quotient (a patch row of Nygren's 10 x 10, whose
#: comparators sit together).
COPY_NODES = 10


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

    @property
    def window_to_quotient(self) -> int:
        """Steps from the window register to the quotient: how far above the terms' columns the sums start."""
        return self.quotient - self.window


@dataclass(frozen=True)
class LaneArithmetic:
    """The shapes of the lane's quantities, from the correlator's parameters.

    Lifted by ``lift = 2**b``, ``2**b - S``, ``M - S + 2**b`` and the quotient lie in ``[1, 2**(b+1) -
    1]`` (``lifted``). ``carried`` holds the dividend ``N`` with mean compensation or, without it, the
    correction ``sum_valid M - Ssum`` (the dividend being ``2**b``); ``bias`` is ``f * 2**b - Ssum``
    (``-Ssum`` without mean compensation). The quotient ``floor(N / f)`` is ``floor(N * m / 2**s)`` with
    ``m = ceil(2**s / f)`` (``reciprocal``, ``s + 1`` bits) and ``s = reciprocal_shift``
    (:func:`reciprocal_shift` for ``f`` up to ``h * w`` and quotients of ``b + 1`` bits); the dividend
    the product takes has ``dividend_bits``.
    """

    depth: Shape
    count: Shape
    window_sum: Shape
    lift: int
    lifted: Shape
    lifted_sum_hi: int
    carried: Shape
    bias: Shape
    value_bits: int
    reciprocal_shift: int
    dividend_bits: int

    @classmethod
    def of(cls, p: CorrelatorParameters) -> LaneArithmetic:
        (h, w), b, widths = p.patch_shape, p.depth_bits, p.widths
        nodes, lift = h * w, 1 << p.depth_bits
        lifted_sum_hi = nodes * (2 * lift - 1)
        return cls(
            depth=signed(b), count=unsigned(widths.count.bits), window_sum=signed(widths.window_sum.bits),
            lift=lift, lifted=unsigned(b + 1), lifted_sum_hi=lifted_sum_hi,
            carried=shape_for(widths.sum_difference.lo, lifted_sum_hi),
            bias=shape_for(-nodes * widths.depth.hi, nodes * (lift - widths.depth.lo)),
            value_bits=widths.accumulator.bits, reciprocal_shift=reciprocal_shift(nodes, b + 1),
            dividend_bits=lifted_sum_hi.bit_length())


def _window_layout(p: CorrelatorParameters) -> data.ArrayLayout:
    """``w`` columns of ``h`` depths: one placement's window, column by column."""
    (h, w) = p.patch_shape
    return data.ArrayLayout(data.ArrayLayout(signed(p.depth_bits), h), w)


class WindowLane(wiring.Component):
    """One lane: the value of one placement per step, from its window seen twice.

    Step-synchronous ports (no stream fits: the lane never stalls, it follows the step enable).

    Latency: let step ``s`` be taken on edge ``e_s`` (``advance`` high in the cycle before it), with
    ``sum_window`` holding placement ``p`` before ``e_s``. ``D = quotient - window`` steps after
    (``PipelineStages.window_to_quotient``) the quotient of ``p`` is loaded on ``e_{s+D-1}``; from that
    edge on, ``term_window`` must hold ``p`` (in the core, the same columns have moved down the window
    register by then), and ``value`` is ``V(p)`` ``term_stages`` clocks after ``e_{s+D-1}``, until the
    next step's value follows. The patch ports, the mode and ``factor`` hold still through a
    correlation; the lane copies the mode and ``factor`` into registers of its own (one clock) and
    forms ``m = ceil(2**s / f)`` from its copy (:class:`SerialReciprocal`, ``reciprocal_bits_per_clock``
    bits a clock, chosen so that ``m`` is final before the first placement's product needs it when
    ``factor`` is final two clocks before the first step; the core gives it three).

    Resources at 10 x 10: 8 of the device's multipliers (MULT18X18D), 4 for the quotient's product
    ``N * m`` (24 x 32 bits) and 4 for ``f * P'`` and ``K * N``.

    Parameters
    ----------
    parameters : CorrelatorParameters
        The correlator's sizes and widths (``lanes`` is not used).
    product : ProductBlock
        How the lane makes the multipliers of ``f * P'`` and ``K * N`` (:class:`RegisteredProduct`, or a
        device's block of the same members and timing: the core's ``product`` option).

    Members
    -------
    advance : ``In(1)``
        The step enable.
    sum_window, term_window : ``In(ArrayLayout(ArrayLayout(signed(b), h), w))``
        The placement's window at the top of the window register (where its sum starts) and at its
        bottom (where its terms are formed), column by column.
    patch_valid : ``In(h * w)``
        The patch's valid bits, node ``k * w + l`` at bit ``k * w + l``.
    lifted_patch : ``In(ArrayLayout(unsigned(b + 1), h * w))``
        ``2**b - S`` at each node.
    mean_compensation : ``In(1)``
    factor : ``In(count)``
        ``f``: ``n`` with mean compensation, 1 without.
    dividend_bias : ``In(bias)``
        ``f * 2**b - Ssum`` with mean compensation, ``-Ssum`` without.
    value : ``Out(unsigned(accumulator_bits))``
        ``V``.
    """

    def __init__(self, *, parameters: CorrelatorParameters, product: ProductBlock = RegisteredProduct):
        checked_parameters(parameters)
        self._product = product
        self._parameters = p = parameters
        self.arithmetic = a = LaneArithmetic.of(p)
        self.stages = PipelineStages.of(window_timing(p.map_shape, p.patch_shape, p.lanes))
        nodes = p.patch_shape[0] * p.patch_shape[1]
        product = reciprocal_product_stages(a.dividend_bits, a.reciprocal_shift + 1)
        #: Quotient stages the dividend waits in before the product takes it (the product fills the last).
        self.quotient_wait = QUOTIENT_STAGES - product
        if self.quotient_wait < 1:
            raise ValueError(f"the quotient's product takes {product} stages, more than the {QUOTIENT_STAGES - 1} it may")
        # The first placement's product takes the reciprocal `lead` steps (at least as many clocks) after the
        # first step; f is final two clocks before that step, the lane's copy of it one clock later.
        lead = self.stages.window_to_quotient - 1 - (product - 1)
        for per_clock in range(1, 5):
            if SerialReciprocal.iterations_for(a.reciprocal_shift, per_clock) <= lead:
                break
        else:
            raise ValueError(f"the reciprocal of f ({a.reciprocal_shift + 1} bits) cannot be made in the {lead} "
                             f"clocks before its first use at patch shape {p.patch_shape}")
        #: Quotient bits the lane's :class:`SerialReciprocal` makes a clock (the fewest that make it in time).
        self.reciprocal_bits_per_clock = per_clock
        super().__init__({
            "advance": In(1),
            "sum_window": In(_window_layout(p)),
            "term_window": In(_window_layout(p)),
            "patch_valid": In(nodes),
            "lifted_patch": In(data.ArrayLayout(a.lifted, nodes)),
            "mean_compensation": In(1),
            "factor": In(a.count),
            "dividend_bias": In(a.bias),
            "value": Out(unsigned(a.value_bits)),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        nodes = self._parameters.patch_shape[0] * self._parameters.patch_shape[1]
        a, patch_valid = self.arithmetic, self.patch_valid
        # The quotient meets every node's comparator: one register would drive h * w of them, so the lane
        # keeps a copy per COPY_NODES consecutive nodes, loaded from one of ``sources`` copies of the
        # quotient's last stage (:func:`reciprocal_quotient`), each serving ``per_source`` of them: a fan-out of a few at each level.
        # A copy is held at zero while none of its nodes is valid (it is then unused): distinct resets
        # keep synthesis from merging the copies.
        copies = -(-nodes // COPY_NODES)
        sources = ceil_log2(copies) if copies > 2 else 1
        per_source = -(-copies // sources)
        group_valid = [patch_valid[c * COPY_NODES:(c + 1) * COPY_NODES].any() for c in range(copies)]
        source_valid = [patch_valid[s * per_source * COPY_NODES:(s + 1) * per_source * COPY_NODES].any()
                        for s in range(sources)]

        # The mode and f reach much of a lane: registers of their own for each of its parts (the
        # dividend and the quotient, the reciprocal; the products hold a copy of f of their own).
        m.submodules.mode = modes = Replicas(1, 2)
        m.d.comb += modes.i.eq(self.mean_compensation)
        mode, term_mode = modes.o[0], modes.o[1]
        m.submodules.factor = factors = Replicas(a.count, 1)
        m.d.comb += factors.i.eq(self.factor)
        m.submodules.reciprocal = reciprocal = SerialReciprocal(
            divisor_bits=a.count.width, shift=a.reciprocal_shift, per_clock=self.reciprocal_bits_per_clock)
        m.d.comb += reciprocal.divisor.eq(factors.o[0])

        quotients, carried_out = self._quotient(m, mode, reciprocal, source_valid)
        above_sum, above_count, carried_at = self._terms(m, quotients, carried_out, group_valid, per_source)
        self._value(m, term_mode, above_sum, above_count, carried_at)
        return m

    def _quotient(self, m: Module, mode: Any, reciprocal: SerialReciprocal, source_valid: list) -> tuple[list, Any]:
        """The step-synchronous half: the masked depths, their sum, the dividend and the quotient's copies."""
        p, a = self._parameters, self.arithmetic
        (h, w), b, widths = p.patch_shape, p.depth_bits, p.widths
        nodes = h * w
        advance, patch_valid = self.advance, self.patch_valid
        # ---- step-synchronous: the window sum of the valid nodes, the dividend, the quotient ----------
        # An invalid node's depth register is held at zero by its synchronous reset: no LUT per bit.
        masked = Signal(data.ArrayLayout(a.depth, nodes), name="masked", reset_less=True)
        for k in range(h):
            for l in range(w):
                x = k * w + l
                with m.If(~patch_valid[x]):
                    m.d.sync += masked[x].eq(0)
                with m.Elif(advance):
                    m.d.sync += masked[x].eq(self.sum_window[l][k])
        m.submodules.window_sum = window_sum = AdderTree(
            count=nodes, leaf=(widths.depth.lo, widths.depth.hi), total=(widths.window_sum.lo, widths.window_sum.hi),
            enable=True, adders_per_register=TREE_ADDERS_PER_REGISTER)
        m.d.comb += [window_sum.en.eq(advance), *(window_sum.leaves[x].eq(masked[x]) for x in range(nodes))]
        # The dividend (or the correction), then t + 2**b = floor(N / f) = floor(N * m / 2**s) over the
        # quotient stages: the dividend waits in the first ones, the product fills the last.
        carried_in = Signal(a.carried, name="carried_in", reset_less=True)
        with m.If(advance):
            m.d.sync += carried_in.eq(window_sum.sum + self.dividend_bias)
        # The carried value waits through the quotient stages in two delays (in block RAM where they are
        # long: :func:`enabled_delay`), the first up to the last waiting stage, where the product takes it.
        waiting = self.quotient_wait
        m.submodules.quotient_carried = waiting_line = enabled_delay(a.carried, waiting - 1)
        m.submodules.quotient_carried_rest = rest_line = enabled_delay(a.carried, QUOTIENT_STAGES - (waiting - 1))
        before = waiting_line.o
        m.d.comb += [waiting_line.i.eq(carried_in), waiting_line.en.eq(advance), rest_line.i.eq(before),
                     rest_line.en.eq(advance)]
        # The product's dividend waits in a register of its own in the last waiting stage, beside the
        # carried value: the multipliers take both operands from registers, and the mode's multiplexer
        # is that register's synchronous reset (to 2**b, held while the mode is off), no LUT.
        dividend_in = Signal(a.dividend_bits, name="dividend_in", reset_less=True)
        with m.If(~mode):
            m.d.sync += dividend_in.eq(a.lift)
        with m.Elif(advance):
            m.d.sync += dividend_in.eq(before)
        quotients = reciprocal_quotient(m, advance, dividend_in, reciprocal.reciprocal, a.reciprocal_shift, b + 1,
                                        [~valid for valid in source_valid], "quotient")
        return quotients, rest_line.o

    def _terms(self, m: Module, quotients: list, carried_out: Any, group_valid: list, per_source: int) -> tuple[Any, Any, dict]:
        """The term half, every clock: the lifted differences above the quotient, their sum and count.

        Returns the two sums and the carried value at the two term stages that read it (by stage).
        """
        p, a, stages = self._parameters, self.arithmetic, self.stages
        (h, w) = p.patch_shape
        nodes = h * w
        copies = len(group_valid)
        patch_valid = self.patch_valid

        # ---- every clock: the lifted differences, those above the quotient and their count, sums ------
        quotient_copy = [Signal(a.lifted, name=f"quotient{c}", reset_less=True) for c in range(copies)]
        for c in range(copies):
            with m.If(~group_valid[c]):
                m.d.sync += quotient_copy[c].eq(0)
            with m.Else():
                m.d.sync += quotient_copy[c].eq(quotients[c // per_source])
        # The dividend (or the correction) beside the term stages, up to the one before the partials.
        # (in block RAM where that is long: :func:`enabled_delay`, loading on every clock), then a register.
        m.submodules.carried = carried_line = enabled_delay(a.carried, stages.sums - 1)
        m.d.comb += [carried_line.i.eq(carried_out), carried_line.en.eq(1)]
        carried_last = Signal(a.carried, name="carried_last", reset_less=True)
        m.d.sync += carried_last.eq(carried_line.o)
        carried_at = {stages.sums - 1: carried_line.o, stages.sums: carried_last}  # by term stage
        difference = Signal(data.ArrayLayout(a.lifted, nodes), name="difference", reset_less=True)
        above = Signal(data.ArrayLayout(a.lifted, nodes), name="above", reset_less=True)
        passed = Signal(nodes, name="passed", reset_less=True)  # not above the quotient (the complement of "chosen")
        lifted_bits = Shape.cast(a.lifted).width
        above_next, passed_next = [], []
        for k in range(h):
            for l in range(w):
                x = k * w + l
                # d' > q by its complement q >= d': the carry of q - d', a sum bit of the carry chain (a
                # comparison's carry out would be rebuilt in LUTs). d' is given a top bit of 1, so that the
                # chain's top sum bit is that carry itself, not its inverse: the polarity of the registers'
                # synchronous resets below, so no LUT inverts it (one a node did, 100 LUT4 a lane). An
                # invalid node's d' is held at 0 by its register's reset, and q >= 0: never chosen, no LUT.
                not_above = (quotient_copy[x // COPY_NODES] - Cat(difference[x], Const(1, 1)))[lifted_bits]
                with m.If(~patch_valid[x]):
                    m.d.sync += difference[x].eq(0)
                with m.Else():
                    m.d.sync += difference[x].eq(self.term_window[l][k] + self.lifted_patch[x])
                # A register's synchronous reset, driven by the carry itself: no LUT.
                above_next.append(Mux(not_above, 0, difference[x]))
                passed_next.append(not_above)
                m.d.sync += [above[x].eq(above_next[x]), passed[x].eq(not_above)]
        return (*self._sums(m, above, passed, above_next, passed_next), carried_at)

    def _sums(self, m: Module, above: Any, passed: Any, above_next: list, passed_next: list) -> tuple[Any, Any]:
        """The chosen differences' sum and count, a clock before their last register: the products hold it
        (:meth:`_partials`), so these are the values it loads."""
        a, nodes = self.arithmetic, len(passed)
        if nodes == 1:
            # No tree: the node's own registers are the last, so the products load what they would.
            return above_next[0], ~passed_next[0]
        m.submodules.above_sum = above_tree = AdderTree(count=nodes, leaf=(0, 2 * a.lift - 1), total=(0, a.lifted_sum_hi),
                                                   adders_per_register=TREE_ADDERS_PER_REGISTER, registered_sum=False)
        m.submodules.above_count = count_tree = AdderTree(count=nodes, leaf=(0, 1), total=(0, nodes),
                                                   adders_per_register=TREE_ADDERS_PER_REGISTER, registered_sum=False)
        m.d.comb += [above_tree.leaves[x].eq(above[x]) for x in range(nodes)]
        # The count's first level is LUTs (two 1-bit leaves a sum), which take the inversion in.
        m.d.comb += [count_tree.leaves[x].eq(~passed[x]) for x in range(nodes)]
        return above_tree.sum, count_tree.sum

    def _value(self, m: Module, term_mode: Any, above_sum: Any, above_count: Any, carried_at: dict) -> None:
        """V from the sums (given a clock before their last register, which the products hold): the products
        as partial products of a multiplier's width, then their sums."""
        a, stages = self.arithmetic, self.stages
        # V = 2 * (f * P' - K * N) - correction, modulo 2**value_bits (V is below it, so exact): the
        # dividend beside the sums' last level, then each product as partial products of a multiplier's
        # width, then their sums (with the correction), then V. The products' operand registers are their
        # own (:class:`RegisteredProduct`), so a device may keep them inside its multipliers.
        value_bits = a.value_bits
        dividend_bits = a.lifted_sum_hi.bit_length()
        dividend = Mux(term_mode, carried_at[stages.sums - 1], a.lift)[:dividend_bits]
        correction = Signal(a.carried, name="correction", reset_less=True)
        m.d.sync += correction.eq(Mux(term_mode, 0, carried_at[stages.partials - 1]))
        sum_partials = self._partials(m, "sum", self.factor, above_sum)
        count_partials = self._partials(m, "count", above_count, dividend)
        doubled_sum = Signal(value_bits, name="doubled_sum", reset_less=True)
        count_product = Signal(value_bits, name="count_product", reset_less=True)
        m.d.sync += [
            doubled_sum.eq((weighted_sum(sum_partials) << 1) - correction),
            count_product.eq(weighted_sum(count_partials)),
        ]
        value = Signal(unsigned(value_bits), name="value", reset_less=True)
        m.d.sync += value.eq(doubled_sum - (count_product << 1))
        m.d.comb += self.value.eq(value)

    def _partials(self, m: Module, name: str, factor: Any, operand: Any) -> list[tuple[int, Signal]]:
        """``factor * operand`` as ``(weight, register)`` partial products, one :class:`RegisteredProduct`
        (the lane's ``product``) of :data:`~lost.hdl.reciprocal.MULTIPLIER_BITS` of the operand each: a clock to their operand
        registers, a register after."""
        partials = []
        for k, (low, piece) in enumerate(partial_pieces(operand, len(operand))):
            m.submodules[f"{name}_product{k}"] = product = self._product(len(factor), len(piece))
            partial = Signal(self.arithmetic.value_bits, name=f"{name}_partial{k}", reset_less=True)
            m.d.comb += [product.a.eq(factor), product.b.eq(piece)]
            m.d.sync += partial.eq(product.p)
            partials.append((low, partial))
        return partials
