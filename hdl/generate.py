"""Verilog of each correlator variant, for Verilator, lint and the FPGA flow.

``python -m lost.hdl.generate --out build/verilog`` writes one file per variant, named after its
top-level module: ``recursive_correlator.v`` and ``window_correlator_l1.v``/``_l4.v`` (the window core
with 1 and 4 lanes), at the paper's 501 x 501 map and 10 x 10 patch unless ``--map``/``--patch`` say
otherwise. ``emit_src=False`` keeps absolute source paths out of the Verilog, so the files are the
same on every machine.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from amaranth.back import verilog
from amaranth.lib import wiring

__all__ = ["VARIANTS", "Variant", "to_verilog", "variant", "write_verilog", "write_variants"]

DEFAULT_MAP_SHAPE = (501, 501)
DEFAULT_PATCH_SHAPE = (10, 10)


@dataclass(frozen=True)
class Variant:
    """One generated correlator: its module name and how to build it for a map and patch size."""

    name: str
    description: str
    build: Callable[..., wiring.Component]


def _recursive(*, map_shape, patch_shape, depth_bits, exclusion_radius):
    from .recursive import RecursiveCorrelator  # imported late: `generate --help` needs no core

    return RecursiveCorrelator(
        map_shape=map_shape, patch_shape=patch_shape, depth_bits=depth_bits, exclusion_radius=exclusion_radius
    )


def _window(lanes: int) -> Callable[..., wiring.Component]:
    def build(*, map_shape, patch_shape, depth_bits, exclusion_radius):
        from .window import WindowCorrelator

        return WindowCorrelator(
            map_shape=map_shape,
            patch_shape=patch_shape,
            depth_bits=depth_bits,
            lanes=lanes,
            exclusion_radius=exclusion_radius,
        )

    return build


#: Every variant the issue asks for, by module (and file) name.
VARIANTS: dict[str, Variant] = {
    v.name: v
    for v in (
        Variant("recursive_correlator", "recursive adder, one term per clock", _recursive),
        Variant("window_correlator_l1", "shift-register window, 1 lane", _window(1)),
        Variant("window_correlator_l4", "shift-register window, 4 lanes", _window(4)),
    )
}


def variant(name: str) -> Variant:
    """The variant called ``name``; a ValueError lists the known ones."""
    try:
        return VARIANTS[name]
    except KeyError:
        raise ValueError(f"unknown correlator variant {name!r}; known: {', '.join(VARIANTS)}") from None


def to_verilog(component: wiring.Component, *, name: str) -> str:
    """The Verilog of ``component`` with top-level module ``name`` and no source locations."""
    return verilog.convert(component, name=name, emit_src=False)


def write_verilog(component: wiring.Component, *, name: str, out: Path) -> Path:
    """Write ``<out>/<name>.v``, rewriting it only when its text changed (keeps Verilator's cache)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}.v"
    text = to_verilog(component, name=name)
    if not path.exists() or path.read_text() != text:
        path.write_text(text)
    return path


def write_variants(
    out: Path,
    *,
    names: Sequence[str] = tuple(VARIANTS),
    map_shape: tuple[int, int] = DEFAULT_MAP_SHAPE,
    patch_shape: tuple[int, int] = DEFAULT_PATCH_SHAPE,
    depth_bits: int = 16,
    exclusion_radius: int = 1,
) -> list[Path]:
    """Write the Verilog of each named variant under ``out``; return the paths written."""
    chosen = [variant(name) for name in names]
    return [
        write_verilog(
            v.build(
                map_shape=tuple(map_shape),
                patch_shape=tuple(patch_shape),
                depth_bits=depth_bits,
                exclusion_radius=exclusion_radius,
            ),
            name=v.name,
            out=out,
        )
        for v in chosen
    ]


def _shape(text: str) -> tuple[int, int]:
    try:
        rows, cols = (int(side) for side in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected ROWSxCOLS such as 501x501, got {text!r}") from None
    return rows, cols


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lost.hdl.generate", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("build/verilog"), help="output folder")
    parser.add_argument("--map", type=_shape, default=DEFAULT_MAP_SHAPE, help="map shape, ROWSxCOLS")
    parser.add_argument("--patch", type=_shape, default=DEFAULT_PATCH_SHAPE, help="patch shape, ROWSxCOLS")
    parser.add_argument("--depth-bits", type=int, default=16)
    parser.add_argument("--exclusion-radius", type=int, default=1)
    parser.add_argument("--variant", action="append", choices=list(VARIANTS), help="repeatable; default all")
    args = parser.parse_args(argv)
    try:
        paths = write_variants(
            args.out,
            names=args.variant or tuple(VARIANTS),
            map_shape=args.map,
            patch_shape=args.patch,
            depth_bits=args.depth_bits,
            exclusion_radius=args.exclusion_radius,
        )
    except ValueError as error:
        parser.error(str(error))
    for path in paths:
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
