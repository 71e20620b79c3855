"""The one table of the correlator's hardware variants: names, numbers, kinds, lanes and cycle models.

The gateware (:mod:`lost.hdl.variants` builds a variant's core), the synthesis flow, the Verilator
benches, the device's identify reply (:class:`lost.model.protocol.DeviceInfo`) and the host's hardware
backends all look a variant up here. Numpy only, like the rest of :mod:`lost.model`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import cycles_recursive, cycles_window
from .cycles import Schedule

__all__ = [
    "DEFAULT_VARIANT",
    "KINDS",
    "VARIANTS",
    "Variant",
    "of_kind",
    "variant",
    "variant_by_id",
    "window_variant",
]

#: The two principles: one absolute-difference unit and an accumulator, or line buffers and lanes.
KINDS = ("recursive", "window")


@dataclass(frozen=True)
class Variant:
    """One hardware variant of the correlator.

    Attributes
    ----------
    name : str
        Its name, the generated Verilog module's name and the ``--variant`` of every command line.
    ident : int
        Its number in the device's identify reply (one byte): 0 the recursive core, L the window core
        of L lanes.
    kind : {"recursive", "window"}
        The principle (:data:`KINDS`).
    lanes : int
        Placements per clock of the window variant; 1 for the recursive one.
    description : str
        One line for listings.
    """

    name: str
    ident: int
    kind: str
    lanes: int
    description: str

    def schedule(
        self,
        map_shape: tuple[int, int],
        patch_shape: tuple[int, int],
        mask: np.ndarray | None = None,
        mean_compensation: bool = True,
        *,
        exclusion_radius: int = 1,
    ) -> Schedule:
        """The cycle model's :class:`~lost.model.cycles.Schedule` of one correlation (ready held high)."""
        if self.kind == "recursive":
            return cycles_recursive.schedule(map_shape, patch_shape, mask, mean_compensation,
                                             exclusion_radius=exclusion_radius)
        return cycles_window.schedule(map_shape, patch_shape, self.lanes, mask, mean_compensation,
                                      exclusion_radius=exclusion_radius)


RECURSIVE = Variant("recursive_correlator", 0, "recursive", 1, "recursive adder, one term per clock")


def _window(lanes: int) -> Variant:
    return Variant(f"window_correlator_l{lanes}", lanes, "window", lanes,
                   f"shift-register window, {lanes} lane{'s' if lanes > 1 else ''}")


#: Every registered variant, by name: the ones generated, linted and simulated by default.
VARIANTS: dict[str, Variant] = {v.name: v for v in (RECURSIVE, _window(1), _window(4))}

#: The variant of the co-simulated device and the board unless one is named.
DEFAULT_VARIANT = "window_correlator_l1"


def variant(name: str | Variant) -> Variant:
    """The variant called ``name`` (a :class:`Variant` passes through); a ValueError lists the known ones."""
    if isinstance(name, Variant):
        return name
    try:
        return VARIANTS[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown correlator variant {name!r}; known: {', '.join(VARIANTS)}") from None


def window_variant(lanes: int) -> Variant:
    """A window variant of any lane count (synthesis sweeps lane counts beyond the registered ones)."""
    if isinstance(lanes, bool) or not isinstance(lanes, (int, np.integer)) or lanes < 1:
        raise ValueError(f"lanes must be a positive integer, got {lanes!r}")
    return VARIANTS.get(f"window_correlator_l{lanes}") or _window(int(lanes))


def of_kind(kind: str, lanes: int = 1) -> Variant:
    """The variant of a kind (:data:`KINDS`) and lane count; a ValueError names a wrong kind or lane count."""
    if kind not in KINDS:
        raise ValueError(f"variant must be one of {KINDS}, got {kind!r}")
    if kind == "recursive":
        if isinstance(lanes, bool) or lanes != 1:
            raise ValueError(f"the recursive core has one lane, got lanes={lanes!r}")
        return RECURSIVE
    return window_variant(lanes)


def variant_by_id(ident: int) -> Variant:
    """The variant a device names by number in its identify reply (0 recursive, 1-255 window of that many lanes)."""
    if ident == 0:
        return RECURSIVE
    if isinstance(ident, (int, np.integer)) and 1 <= ident <= 255:
        return window_variant(int(ident))
    raise ValueError(f"a device reported variant number {ident!r}, which no variant has")
