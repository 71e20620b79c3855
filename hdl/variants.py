"""The gateware of each correlator variant: its Amaranth class and its core at given sizes.

The variants themselves (names, numbers, kinds, lanes, cycle models) are :mod:`lost.model.variants`;
this module adds what only the gateware knows. Importing it needs no Amaranth: the core classes are
imported when asked for.
"""

from __future__ import annotations

from typing import Any

from lost.model.variants import Variant, variant

__all__ = ["build_core", "core_class"]

MEMORIES = ("on-chip", "external")


def core_class(which: str | Variant, *, memory: str = "on-chip") -> type:
    """The Amaranth class: with its map in block RAM (``"on-chip"``) or reading it through a port (``"external"``)."""
    if memory not in MEMORIES:
        raise ValueError(f"memory must be 'on-chip' or 'external', got {memory!r}")
    if variant(which).kind == "recursive":
        from .recursive import RecursiveCore, RecursiveCorrelator

        return RecursiveCorrelator if memory == "on-chip" else RecursiveCore
    from .window import WindowCore, WindowCorrelator

    return WindowCorrelator if memory == "on-chip" else WindowCore


def build_core(
    which: str | Variant,
    *,
    map_shape: tuple[int, int],
    patch_shape: tuple[int, int],
    depth_bits: int = 16,
    exclusion_radius: int = 1,
    memory: str = "on-chip",
    **options: Any,
):
    """The gateware of a variant at these sizes (``options`` go to the class, e.g. ``enable_buffer``)."""
    registered = variant(which)
    sizes = {"map_shape": tuple(map_shape), "patch_shape": tuple(patch_shape), "depth_bits": depth_bits,
             "exclusion_radius": exclusion_radius}
    if registered.kind == "window":
        sizes["lanes"] = registered.lanes
    return core_class(registered, memory=memory)(**sizes, **options)
