"""Verilog of each correlator variant, for Verilator, lint and the FPGA flow.

``python -m lost.hdl.flow.generate --out build/verilog`` writes one file per variant, named after its
top-level module: ``recursive_correlator.v`` and ``window_correlator_l1.v``/``_l4.v`` (the window core
with 1 and 4 lanes), at the paper's 501 x 501 map and 10 x 10 patch unless ``--map``/``--patch`` say
otherwise. ``emit_src=False`` keeps absolute source paths out of the Verilog, so the files are the
same on every machine.

Yosys writes a memory's initial contents one element per line: 251 001 lines for the map memory of a
501 x 501 core, which Verilator turns into a C++ function that takes minutes to compile. Every memory
of the correlator starts at zero (``init=[]``), so :func:`to_verilog` rewrites each all-zero
initializer as the equivalent ``for`` loop; a memory with any non-zero initial word keeps Yosys's text.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from pathlib import Path

from amaranth.back import verilog
from amaranth.lib import wiring

from lost.hdl.variants import build_core
from lost.model.paper import PAPER_MAP_SHAPE, PAPER_PATCH_SHAPE
from lost.model.shapes import shape_argument
from lost.model.variants import VARIANTS, variant

__all__ = ["compact_zero_initializers", "to_verilog", "write_verilog", "write_variants"]

DEFAULT_MAP_SHAPE = PAPER_MAP_SHAPE
DEFAULT_PATCH_SHAPE = PAPER_PATCH_SHAPE


_INITIAL_BLOCK = re.compile(r"^  initial begin\n((?:    .+\[\d+\] = \d+'h[0-9a-fA-F]+;\n)+)  end\n", re.MULTILINE)
_ELEMENT = re.compile(r"^    (?P<memory>.+)\[(?P<index>\d+)\] = (?P<width>\d+)'h(?P<value>[0-9a-fA-F]+);$")


def compact_zero_initializers(text: str) -> str:
    """Rewrite each memory initializer that sets elements ``0 .. N-1`` to zero as one ``for`` loop.

    The result means the same in Verilog; initializers of any other form are left as Yosys wrote them.
    """
    counter = 0

    def compact(block: re.Match) -> str:
        nonlocal counter
        elements = [_ELEMENT.match(line) for line in block[1].splitlines()]
        memories = {e["memory"] for e in elements if e}
        if (
            not all(elements)
            or len(memories) != 1
            or any(int(e["index"]) != k or int(e["value"], 16) != 0 for k, e in enumerate(elements))
        ):
            return block[0]
        (memory,) = memories
        index = f"lost_zero_init_{counter}"
        counter += 1
        return (
            f"  integer {index};\n"
            "  initial begin\n"
            f"    for ({index} = 0; {index} < {len(elements)}; {index} = {index} + 1)\n"
            f"      {memory}[{index}] = {elements[0]['width']}'h0;\n"
            "  end\n"
        )

    if "lost_zero_init_" in text:
        raise ValueError("the Verilog already uses the name prefix lost_zero_init_; cannot compact it")
    return _INITIAL_BLOCK.sub(compact, text)


def to_verilog(component: wiring.Component, *, name: str) -> str:
    """The Verilog of ``component`` with top-level module ``name``, no source locations, and its
    all-zero memory initializers compacted (:func:`compact_zero_initializers`)."""
    return compact_zero_initializers(verilog.convert(component, name=name, emit_src=False))


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
            build_core(
                v,
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


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lost.hdl.flow.generate", description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("build/verilog"), help="output folder")
    parser.add_argument("--map", type=shape_argument, default=DEFAULT_MAP_SHAPE, help="map shape, ROWSxCOLS")
    parser.add_argument("--patch", type=shape_argument, default=DEFAULT_PATCH_SHAPE, help="patch shape, ROWSxCOLS")
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
