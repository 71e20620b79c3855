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
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from amaranth.hdl import Cat, Module, Mux, Shape, Signal, signed, unsigned
from amaranth.lib import data, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import ceil_log2

from lost.hdl.blocks import AdderTree, DelayLine, Replicas, shape_for
from lost.hdl.interface import CorrelatorParameters
from lost.model.cycles_window import QUOTIENT_STAGES, WindowTiming, window_timing

__all__ = ["MULTIPLIER_BITS", "LaneArithmetic", "PipelineStages", "WindowLane", "pipelined_quotient"]

#: The operand width of the device's multipliers (the ECP5's MULT18X18D): a product's wide operand is
#: split there, so that each partial product is one multiplier with registers on both sides.
MULTIPLIER_BITS = 18

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
    (``-Ssum`` without mean compensation).
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
            value_bits=widths.accumulator.bits)


def pipelined_quotient(m: Module, enable: Any, dividend: Any, divisors: list, quotient_bits: int, stages: int,
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
    correlation; the lane copies the mode and ``factor`` into registers of its own (one clock).

    Parameters
    ----------
    parameters : CorrelatorParameters
        The correlator's sizes and widths (``lanes`` is not used).

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

    def __init__(self, *, parameters: CorrelatorParameters):
        if not isinstance(parameters, CorrelatorParameters):
            raise ValueError(f"parameters must be a CorrelatorParameters, got {parameters!r}")
        self._parameters = p = parameters
        self.arithmetic = a = LaneArithmetic.of(p)
        self.stages = PipelineStages.of(window_timing(p.map_shape, p.patch_shape, p.lanes))
        nodes = p.patch_shape[0] * p.patch_shape[1]
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
        p, a, stages = self._parameters, self.arithmetic, self.stages
        (h, w), b, widths = p.patch_shape, p.depth_bits, p.widths
        nodes = h * w
        advance, patch_valid = self.advance, self.patch_valid
        # The quotient meets every node's comparator: one register would drive h * w of them, so the lane
        # keeps a copy per COPY_NODES consecutive nodes, loaded from one of ``sources`` copies of the
        # divider's last stage, each serving ``per_source`` of them: a fan-out of a few at each level.
        # A copy is held at zero while none of its nodes is valid (it is then unused): distinct resets
        # keep synthesis from merging the copies.
        copies = -(-nodes // COPY_NODES)
        sources = ceil_log2(copies) if copies > 2 else 1
        per_source = -(-copies // sources)
        group_valid = [patch_valid[c * COPY_NODES:(c + 1) * COPY_NODES].any() for c in range(copies)]
        source_valid = [patch_valid[s * per_source * COPY_NODES:(s + 1) * per_source * COPY_NODES].any()
                        for s in range(sources)]

        # The mode and f reach much of a lane: registers of their own for each of its parts (the
        # dividend, each run of quotient stages, the products).
        m.submodules.mode = modes = Replicas(1, 2)
        m.d.comb += modes.i.eq(self.mean_compensation)
        mode, term_mode = modes.o[0], modes.o[1]
        divider_copies = -(-QUOTIENT_STAGES // 6)
        m.submodules.factor = factors = Replicas(a.count, divider_copies + 1)
        m.d.comb += factors.i.eq(self.factor)
        divisors = [factors.o[r] for r in range(divider_copies)]
        lane_factor = factors.o[divider_copies]

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
            enable=True)
        m.d.comb += [window_sum.en.eq(advance), *(window_sum.leaves[x].eq(masked[x]) for x in range(nodes))]
        # The dividend (or the correction), then t + 2**b = floor(N / f) over the quotient stages.
        carried_in = Signal(a.carried, name="carried_in", reset_less=True)
        with m.If(advance):
            m.d.sync += carried_in.eq(window_sum.sum + self.dividend_bias)
        quotients, carried_out = pipelined_quotient(
            m, advance, Mux(mode, carried_in, a.lift), divisors, b + 1, QUOTIENT_STAGES, carried_in,
            [~valid for valid in source_valid], "quotient")

        # ---- every clock: the lifted differences, those above the quotient and their count, sums ------
        quotient_copy = [Signal(a.lifted, name=f"quotient{c}", reset_less=True) for c in range(copies)]
        for c in range(copies):
            with m.If(~group_valid[c]):
                m.d.sync += quotient_copy[c].eq(0)
            with m.Else():
                m.d.sync += quotient_copy[c].eq(quotients[c // per_source])
        # The dividend (or the correction) beside the term stages, up to the one before the partials.
        m.submodules.carried = carried_line = DelayLine(a.carried, stages.sums, reset_less=True)
        m.d.comb += carried_line.i.eq(carried_out)
        carried_at = list(carried_line.taps)  # carried_at[stage - 1]: the carried value of that stage
        difference = Signal(data.ArrayLayout(a.lifted, nodes), name="difference", reset_less=True)
        above = Signal(data.ArrayLayout(a.lifted, nodes), name="above", reset_less=True)
        selected = Signal(nodes, name="selected", reset_less=True)
        for k in range(h):
            for l in range(w):
                x = k * w + l
                # d' > q as the sign of q - d': a sum bit of the carry chain, where a comparison's
                # carry out would be rebuilt in LUTs.
                chosen = patch_valid[x] & (quotient_copy[x // COPY_NODES] - difference[x])[-1]
                m.d.sync += [
                    difference[x].eq(self.term_window[l][k] + self.lifted_patch[x]),
                    # A register's synchronous reset: one LUT per node, none per bit.
                    above[x].eq(Mux(chosen, difference[x], 0)),
                    selected[x].eq(chosen),
                ]
        m.submodules.above_sum = above_tree = AdderTree(count=nodes, leaf=(0, 2 * a.lift - 1), total=(0, a.lifted_sum_hi))
        m.submodules.above_count = count_tree = AdderTree(count=nodes, leaf=(0, 1), total=(0, nodes))
        m.d.comb += [above_tree.leaves[x].eq(above[x]) for x in range(nodes)]
        m.d.comb += [count_tree.leaves[x].eq(selected[x]) for x in range(nodes)]
        above_sum, above_count = above_tree.sum, count_tree.sum

        # V = 2 * (f * P' - K * N) - correction, modulo 2**value_bits (V is below it, so exact): the
        # dividend beside the sums' last level, then each product as two partial products of a
        # multiplier's width, then their sums (with the correction), then V.
        value_bits = a.value_bits
        dividend = Signal(a.lifted_sum_hi.bit_length(), name="dividend", reset_less=True)
        m.d.sync += dividend.eq(Mux(term_mode, carried_at[stages.sums - 2], a.lift))
        correction = Signal(a.carried, name="correction", reset_less=True)
        m.d.sync += correction.eq(Mux(term_mode, 0, carried_at[stages.partials - 2]))
        partials = Signal(data.ArrayLayout(unsigned(value_bits), 4), name="partials", reset_less=True)
        m.d.sync += [
            partials[0].eq(lane_factor * above_sum[:MULTIPLIER_BITS]),
            partials[1].eq(lane_factor * above_sum[MULTIPLIER_BITS:]),
            partials[2].eq(above_count * dividend[:MULTIPLIER_BITS]),
            partials[3].eq(above_count * dividend[MULTIPLIER_BITS:]),
        ]
        doubled_sum = Signal(value_bits, name="doubled_sum", reset_less=True)
        count_product = Signal(value_bits, name="count_product", reset_less=True)
        m.d.sync += [
            doubled_sum.eq(((partials[0] + (partials[1] << MULTIPLIER_BITS)) << 1) - correction),
            count_product.eq(partials[2] + (partials[3] << MULTIPLIER_BITS)),
        ]
        value = Signal(unsigned(value_bits), name="value", reset_less=True)
        m.d.sync += value.eq(doubled_sum - (count_product << 1))
        m.d.comb += self.value.eq(value)
        return m
