"""The window lane's quotient by a reciprocal: ``q = floor(N / f)`` without a divider per placement.

``f`` (the patch's valid-node count) holds still through a correlation, so each lane forms
``m = ceil(2**s / f)`` once, serially (:class:`SerialReciprocal`), and ``q = floor(N * m / 2**s)`` is a
product on the device's multipliers (:func:`reciprocal_quotient`), exact for every dividend the lane can
see (:func:`reciprocal_shift` proves the bound).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from amaranth.hdl import Cat, Module, Mux, Signal, unsigned
from amaranth.lib import wiring
from amaranth.lib.wiring import In, Out

from lost.hdl.blocks import tree_levels

__all__ = [
    "MULTIPLIER_BITS",
    "SerialReciprocal",
    "partial_pieces",
    "reciprocal_product_stages",
    "reciprocal_quotient",
    "reciprocal_shift",
    "weighted_sum",
]

#: The operand width of the device's multipliers (the ECP5's MULT18X18D): a product's wide operand is
#: split there, so that each partial product is one multiplier with registers on both sides.
MULTIPLIER_BITS = 18


def reciprocal_shift(max_divisor: int, quotient_bits: int) -> int:
    """The shift ``s`` that makes ``floor(N * ceil(2**s / f) / 2**s)`` equal ``floor(N / f)``.

    For every divisor ``f`` in ``[1, max_divisor]`` and every dividend ``N`` in ``[0, f * 2**Q)``
    (``Q = quotient_bits``: the quotient fits ``Q`` bits, as a restoring divider of ``Q`` stages also needs),
    ``s = Q + bit_length(F * (F - 1))`` with ``F = max_divisor``.

    Proof: write ``N = q * f + r`` with ``0 <= r < f``, and ``m = ceil(2**s / f) = (2**s + e) / f``
    with ``0 <= e <= f - 1``. Then ``N * m / 2**s = q + (r + N * e / 2**s) / f``. As ``N < f * 2**Q``,
    ``N * e < f * (f - 1) * 2**Q <= F * (F - 1) * 2**Q < 2**s`` (or ``e = 0`` when ``f = 1``), so
    ``0 <= r + N * e / 2**s < r + 1 <= f`` and the floor is ``q``.
    """
    if max_divisor < 1 or quotient_bits < 1:
        raise ValueError(f"max_divisor and quotient_bits must be positive, got {max_divisor}, {quotient_bits}")
    return quotient_bits + (max_divisor * (max_divisor - 1)).bit_length()


class SerialReciprocal(wiring.Component):
    """``ceil(2**shift / divisor)``, by restoring division of ``2**shift + divisor - 1``, ``per_clock`` bits a clock.

    A per-correlation constant needs no divider per placement: this one starts again whenever
    ``divisor`` differs from the one it last took (and after a reset), and holds its result until the
    divisor changes. A divisor of 0 gives some value (no placement uses it: the patch has no valid node).

    Latency: with ``divisor`` changed before edge ``e``, ``reciprocal`` is final from edge ``e + 1 +
    iterations`` on (:attr:`latency` ``= 1 + iterations``, ``iterations = ceil((shift + 1) /
    per_clock)``); it changes only when a new run starts, so it is never a mix of two runs once final.

    Parameters
    ----------
    divisor_bits : int
    shift : int
        ``s``; the result has ``s + 1`` bits (``2**s`` for a divisor of 1).
    per_clock : int
        Quotient bits made a clock (each one a subtraction and a multiplexer in series).

    Members
    -------
    divisor : ``In(divisor_bits)``
    reciprocal : ``Out(shift + 1)``
    """

    def __init__(self, *, divisor_bits: int, shift: int, per_clock: int = 2):
        if min(divisor_bits, shift, per_clock) < 1:
            raise ValueError(f"divisor_bits, shift and per_clock must be positive, got {divisor_bits}, {shift}, {per_clock}")
        self._divisor_bits, self._shift, self._per_clock = divisor_bits, shift, per_clock
        self.iterations = self.iterations_for(shift, per_clock)
        super().__init__({"divisor": In(divisor_bits), "reciprocal": Out(shift + 1)})

    @staticmethod
    def iterations_for(shift: int, per_clock: int) -> int:
        """Clocks a run takes: ``ceil((shift + 1) / per_clock)``."""
        return -(-(shift + 1) // per_clock)

    @property
    def latency(self) -> int:
        return 1 + self.iterations

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        bits, shift = self._divisor_bits, self._shift
        # One register holds the dividend bits still to take (at the top) and the quotient bits made
        # (shifted in at the bottom); leading zeros pad it to whole iterations and leave zeros.
        word = Signal(self.iterations * self._per_clock, name="word")
        remainder = Signal(bits, name="remainder")
        divisor = Signal(bits, name="held_divisor")
        left = Signal(range(self.iterations + 1), name="left", init=self.iterations)
        started = Signal(name="started")  # a reset starts a run too
        with m.If(~started | (self.divisor != divisor)):
            low = Signal(shift, name="divisor_less_one")
            m.d.comb += low.eq(self.divisor - 1)  # below 2**shift for every divisor in [1, 2**shift]
            m.d.sync += [started.eq(1), divisor.eq(self.divisor), word.eq(Cat(low, 1)), remainder.eq(0),
                         left.eq(self.iterations)]
        with m.Elif(left != 0):
            value, rest = word, remainder
            for _ in range(self._per_clock):
                trial = Cat(value[-1], rest)  # 2 * remainder + the next dividend bit, below 2 * divisor
                reduced = trial - divisor
                fits = ~reduced[-1]
                rest = Mux(fits, reduced, trial)[:bits]
                value = Cat(fits, value[:-1])
            m.d.sync += [word.eq(value), remainder.eq(rest), left.eq(left - 1)]
        m.d.comb += self.reciprocal.eq(word)
        return m


def partial_pieces(value: Any, width: int) -> list[tuple[int, Any]]:
    """``value``'s ``width`` bits as multiplier operands: ``(weight, bits)``, :data:`MULTIPLIER_BITS` at a time."""
    return [(low, value[low:min(low + MULTIPLIER_BITS, width)]) for low in range(0, width, MULTIPLIER_BITS)]


def weighted_sum(terms: list[tuple[int, Any]]) -> Any:
    """The sum of ``(weight, value)`` terms, each shifted up by its weight."""
    (first_weight, first), *rest = terms
    return sum((value << weight for weight, value in rest), first << first_weight)


def _trimmed(terms: list[tuple[int, Any]], low: int, top: int) -> list[tuple[int, Any]]:
    """Weighted terms with only what a sum's bits in ``[low, top)`` need.

    Bits at or above ``top`` never reach a lower one, so each term keeps only its bits below it (a
    term wholly above goes). The term of least weight, alone up to the next weight, adds its bits
    there to nothing, so they carry nothing: its bits below ``min(next weight, low)`` go.
    """
    terms = sorted(((weight, value) for weight, value in terms if weight < top), key=lambda term: term[0])
    if len(terms) > 1 and terms[0][0] < min(terms[1][0], low):
        (weight, value), cut = terms[0], min(terms[1][0], low)
        terms[0] = (cut, value[cut - weight:])
    return [(weight, value[:top - weight]) for weight, value in terms if len(value[:top - weight])]


def reciprocal_product_stages(dividend_bits: int, reciprocal_bits: int) -> int:
    """Loads :func:`reciprocal_quotient` takes: the partial products, the levels of their sum, the copies."""
    terms = len(range(0, dividend_bits, MULTIPLIER_BITS)) * len(range(0, reciprocal_bits, MULTIPLIER_BITS))
    return 1 + max(tree_levels(terms), 1)


def reciprocal_quotient(m: Module, enable: Any, dividend: Any, reciprocal: Any, shift: int, quotient_bits: int,
                        holds: Sequence[Any], name: str) -> list:
    """``floor(dividend * reciprocal / 2**shift)`` (``quotient_bits`` bits) in registers loaded on ``enable``.

    The product is split into partial products of :data:`MULTIPLIER_BITS`-bit operands, one device
    multiplier each, registered; their weighted sum is formed by a tree of adders, a register after
    each level but the last, which loads one register per signal in ``holds``, held at zero while its
    signal is high: copies for a wide fan-out, which distinct resets keep synthesis from merging. Only
    the sum's bits below ``shift + quotient_bits`` are formed, and of the lowest partial product only
    what can carry (:func:`_trimmed`), so the quotient is exact whenever it fits ``quotient_bits``.
    ``reciprocal`` must hold still. Returns the copies, :func:`reciprocal_product_stages` loads later.
    """
    top = shift + quotient_bits
    products = [(a + b, a_bits * b_bits) for a, a_bits in partial_pieces(dividend, len(dividend))
                for b, b_bits in partial_pieces(reciprocal, len(reciprocal))]
    terms = []
    for k, (weight, product) in enumerate(_trimmed(products, shift, top)):
        register = Signal(len(product), name=f"{name}_product{k}", reset_less=True)
        with m.If(enable):
            m.d.sync += register.eq(product)
        terms.append((weight, register))
    level = 0
    while len(terms) > 2:
        level += 1
        summed = []
        for k in range(0, len(terms), 2):
            if k + 1 == len(terms):
                summed.append(terms[k])
                continue
            (low, first), (high, second) = terms[k], terms[k + 1]
            register = Signal(top - low, name=f"{name}_sum{level}_{k // 2}", reset_less=True)
            with m.If(enable):
                m.d.sync += register.eq(first + (second << (high - low)))
            summed.append((low, register))
        terms = _trimmed(summed, shift, top)
    total_weight, total = terms[0][0], terms[0][1]
    if len(terms) == 2:
        (low, first), (high, second) = terms
        total = first + (second << (high - low))
    quotient = (total >> (shift - total_weight))[:quotient_bits]
    copies = [Signal(unsigned(quotient_bits), name=f"{name}_copy{c}", reset_less=True) for c in range(len(holds))]
    for copy, hold in zip(copies, holds):
        with m.If(hold):
            m.d.sync += copy.eq(0)
        with m.Elif(enable):
            m.d.sync += copy.eq(quotient)
    return copies
