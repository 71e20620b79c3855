"""The one registry of the correlator's hardware variants.

Verilog generation (:mod:`lost.hdl.flow.generate`), synthesis (:mod:`lost.hdl.flow.synth`), the Verilator
benches (:mod:`lost.sim`), the device top-level (:mod:`lost.hdl.device`), the host's hardware
backends and the tests all look a variant up here: its name (also the Verilog module's), its core
classes, its lane count, its number on the wire (the device's identify reply) and its cycle model.

Importing this module needs no Amaranth: the core classes are imported when asked for.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["DEFAULT_VARIANT", "VARIANTS", "Variant", "variant", "variant_by_id"]


@dataclass(frozen=True)
class Variant:
    """One hardware variant of the correlator.

    Attributes
    ----------
    name : str
        Its name, the generated Verilog module's name and the ``--variant`` of every command line.
    ident : int
        Its number in the device's identify reply (one byte).
    kind : {"recursive", "window"}
        The principle: one absolute-difference unit and an accumulator, or line buffers and lanes.
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

    def core_class(self, *, memory: str = "on-chip") -> type:
        """The Amaranth class: with its map in block RAM (``"on-chip"``) or reading it through a port (``"external"``)."""
        if memory not in ("on-chip", "external"):
            raise ValueError(f"memory must be 'on-chip' or 'external', got {memory!r}")
        if self.kind == "recursive":
            from .recursive import RecursiveCore, RecursiveCorrelator

            return RecursiveCorrelator if memory == "on-chip" else RecursiveCore
        from .window import WindowCore, WindowCorrelator

        return WindowCorrelator if memory == "on-chip" else WindowCore

    def build(
        self,
        *,
        map_shape: tuple[int, int],
        patch_shape: tuple[int, int],
        depth_bits: int = 16,
        exclusion_radius: int = 1,
        memory: str = "on-chip",
        **options: Any,
    ):
        """The gateware of this variant at these sizes (``options`` go to the class, e.g. ``enable_buffer``)."""
        sizes = {"map_shape": tuple(map_shape), "patch_shape": tuple(patch_shape), "depth_bits": depth_bits,
                 "exclusion_radius": exclusion_radius}
        if self.kind == "window":
            sizes["lanes"] = self.lanes
        return self.core_class(memory=memory)(**sizes, **options)

    def schedule(
        self,
        map_shape: tuple[int, int],
        patch_shape: tuple[int, int],
        mask: np.ndarray | None = None,
        mean_compensation: bool = True,
        *,
        exclusion_radius: int = 1,
    ):
        """The cycle model's :class:`~lost.model.cycles.Schedule` of one correlation (ready held high)."""
        from lost.model import cycles_recursive, cycles_window

        if self.kind == "recursive":
            return cycles_recursive.schedule(map_shape, patch_shape, mask, mean_compensation, exclusion_radius=exclusion_radius)
        return cycles_window.schedule(map_shape, patch_shape, self.lanes, mask, mean_compensation, exclusion_radius=exclusion_radius)


#: Every variant, by name; the ones generated, linted and simulated by default.
VARIANTS: dict[str, Variant] = {
    v.name: v
    for v in (
        Variant("recursive_correlator", 0, "recursive", 1, "recursive adder, one term per clock"),
        Variant("window_correlator_l1", 1, "window", 1, "shift-register window, 1 lane"),
        Variant("window_correlator_l4", 4, "window", 4, "shift-register window, 4 lanes"),
    )
}

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
    if isinstance(lanes, bool) or not isinstance(lanes, int) or lanes < 1:
        raise ValueError(f"lanes must be a positive integer, got {lanes!r}")
    name = f"window_correlator_l{lanes}"
    return VARIANTS.get(name) or Variant(name, lanes, "window", lanes, f"shift-register window, {lanes} lanes")


def variant_by_id(ident: int) -> Variant:
    """The variant a device names by number in its identify reply."""
    for v in VARIANTS.values():
        if v.ident == ident:
            return v
    if 1 <= ident <= 255:
        return window_variant(ident)
    raise ValueError(f"a device reported variant number {ident}, which no variant has")
