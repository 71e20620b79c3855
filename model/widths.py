"""Bit widths of every intermediate of the exact correlator, derived from the definition.

The gateware sizes its adders from :func:`correlator_widths`, the software backends choose their
integer types from it, and the tests check that the bounds are reached by extreme inputs, so a bound
is neither guessed nor loose by more than the rounding up to whole bits.

Notation: ``b`` depth bits (two's complement, so a depth lies in ``[-2**(b-1), 2**(b-1) - 1]``),
``D = 2**b - 1`` the largest difference of two depths, ``n <= h * w`` valid patch nodes,
``d_k = M_k - S_k`` the difference at patch node ``k``.

=====================  ==========================================  =========================================
intermediate           formula                                     bound, derivation
=====================  ==========================================  =========================================
``difference``         ``M - S``                                   ``|d| <= D``
``abs_difference``     ``|M - S|`` (one term, plain mode)          ``<= D``
``column_sum``         ``sum of h map words of one column``        ``h * [min, max]``
``window_sum``         ``sum_valid M`` (also ``sum_valid S``)      ``n * [min, max]``
``scaled_depth``       ``n * M`` (also ``n * S``)                  ``n * [min, max]``
``sum_difference``     ``sum_valid M - sum_valid S``               ``|.| <= n * D``
``centred_depth``      ``n * M_k - sum_valid M``                   ``= sum_{l != k} (M_k - M_l)``, so
                       (also ``n * S_k - sum_valid S``)            ``|.| <= (n - 1) * D``
``term``               ``n * d_k - sum_valid d``                   ``= sum_{l != k} (d_k - d_l)``, so
                                                                   ``|.| <= (n - 1) * 2 * D``
``abs_term``           ``|term|``                                  ``<= (n - 1) * 2 * D``
``surface``            ``V`` with mean compensation                ``= n * sum_k |d_k - mean(d)|``; for
                                                                   ``d_k`` in an interval of length ``2D``
                                                                   the sum of absolute deviations is
                                                                   largest with ``floor(n/2)`` at one end
                                                                   and the rest at the other, giving
                                                                   ``V <= 4 * floor(n**2 / 4) * D``
``surface_plain``      ``V`` without mean compensation             ``<= n * D``
``accumulator``        running sum of either mode's terms          ``max(surface, surface_plain)``; terms are
                                                                   non-negative, so partial sums stay below
                                                                   the total
=====================  ==========================================  =========================================

For the supported sizes (16-bit depths, maps up to 1024 x 1024, patches up to 16 x 16), as computed
by :func:`correlator_widths` (``tests/model/test_widths.py`` checks this table against it):

============  ======  ======  ========  ====  ========  =======  =======  ===========
patch         window  scaled  centred   term  abs_term  surface  surface  accumulator
              sum     depth   depth                              plain
============  ======  ======  ========  ====  ========  =======  =======  ===========
10 x 10       23      23      24        25    24        30       23       30
16 x 16       24      24      25        26    25        32       24       32
============  ======  ======  ========  ====  ========  =======  =======  ===========

All signed but the ``abs_*``, ``surface*`` and ``accumulator`` rows, which are unsigned. A 10 x 10
surface fits a signed 32-bit integer; a 16 x 16 one needs 32 unsigned bits, so software keeps int64
sums there. Placement indices need ``(H - h).bit_length()`` and ``(W - w).bit_length()`` bits
(:func:`placement_widths`).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

__all__ = ["Bound", "CorrelatorWidths", "correlator_widths", "placement_widths", "bits_for"]

MAX_PATCH_NODES = 16 * 16
MAX_MAP_SIDE = 1024


def bits_for(lo: int, hi: int) -> tuple[int, bool]:
    """Smallest two's complement (when ``lo < 0``) or unsigned width holding ``[lo, hi]``."""
    if lo > hi:
        raise ValueError(f"empty range [{lo}, {hi}]")
    if lo >= 0:
        return max(hi.bit_length(), 1), False
    # A signed width b holds [-2**(b-1), 2**(b-1) - 1].
    return max((-lo - 1).bit_length(), hi.bit_length()) + 1, True


@dataclass(frozen=True)
class Bound:
    """The exact range of one intermediate and the width that holds it."""

    lo: int
    hi: int

    @property
    def bits(self) -> int:
        return bits_for(self.lo, self.hi)[0]

    @property
    def signed(self) -> bool:
        return bits_for(self.lo, self.hi)[1]


@dataclass(frozen=True)
class CorrelatorWidths:
    """Bounds of every intermediate for one patch size and depth width; see the module docstring."""

    depth: Bound
    count: Bound
    difference: Bound
    abs_difference: Bound
    column_sum: Bound
    window_sum: Bound
    scaled_depth: Bound
    sum_difference: Bound
    centred_depth: Bound
    term: Bound
    abs_term: Bound
    surface: Bound
    surface_plain: Bound
    accumulator: Bound

    def as_dict(self) -> dict[str, tuple[int, bool]]:
        """``{name: (bits, signed)}`` for every intermediate."""
        return {f.name: (getattr(self, f.name).bits, getattr(self, f.name).signed) for f in fields(self)}


def correlator_widths(h: int, w: int, depth_bits: int = 16) -> CorrelatorWidths:
    """Bounds of every intermediate of the correlator for an ``h x w`` patch of ``depth_bits`` words.

    The bounds hold for any mask (``n`` from 1 to ``h * w``): each grows with ``n``.

    Raises
    ------
    ValueError
        Non-positive sizes, or a depth width below 2 bits.
    """
    for name, value in (("h", h), ("w", w)):
        if not isinstance(value, int) or value < 1:
            raise ValueError(f"patch side {name} must be a positive integer, got {value!r}")
    if not isinstance(depth_bits, int) or depth_bits < 2:
        raise ValueError(f"depth_bits must be an integer of at least 2, got {depth_bits!r}")
    lo, hi = -(2 ** (depth_bits - 1)), 2 ** (depth_bits - 1) - 1
    D = hi - lo
    n = h * w
    surface = 4 * (n * n // 4) * D
    return CorrelatorWidths(
        depth=Bound(lo, hi),
        count=Bound(1, n),
        difference=Bound(-D, D),
        abs_difference=Bound(0, D),
        column_sum=Bound(h * lo, h * hi),
        window_sum=Bound(n * lo, n * hi),
        scaled_depth=Bound(n * lo, n * hi),
        sum_difference=Bound(-n * D, n * D),
        centred_depth=Bound(-(n - 1) * D, (n - 1) * D),
        term=Bound(-(n - 1) * 2 * D, (n - 1) * 2 * D),
        abs_term=Bound(0, (n - 1) * 2 * D),
        surface=Bound(0, surface),
        surface_plain=Bound(0, n * D),
        accumulator=Bound(0, max(surface, n * D)),
    )


def placement_widths(map_shape: tuple[int, int], patch_shape: tuple[int, int]) -> tuple[int, int]:
    """Unsigned widths of the row and column index of a placement."""
    (H, W), (h, w) = map_shape, patch_shape
    if h > H or w > W:
        raise ValueError(f"patch of shape {patch_shape} is larger than the map of shape {map_shape}")
    return max((H - h).bit_length(), 1), max((W - w).bit_length(), 1)
