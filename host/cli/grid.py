"""``lost grid FILE... --node-m M [--crs CRS] --out GRID.nc``: a bathymetry grid (mean, count, std per node) from survey files."""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from ..errors import UsageError
from .common import positive_metres

__all__ = ["register"]


def _cmd_grid(args: argparse.Namespace) -> int:
    from ..io.survey_grid import grid_survey, write_survey_grid

    out = args.grid_out
    if out.is_dir():
        raise UsageError(f"--out {out} is a folder; name the NetCDF file to write, e.g. {out / 'grid.nc'}")
    if out.exists() and not args.replace:
        raise UsageError(f"{out} exists; pass --replace to write over it")
    if not out.parent.is_dir():
        raise ValueError(f"no folder {out.parent} to write {out.name} into")
    result = grid_survey(args.files, node_m=args.node_m, crs=args.crs)
    write_survey_grid(result, out, history=shlex.join(["lost", *sys.argv[1:]]))
    g = result.grid
    filled = int((result.count > 0).sum())
    print(f"{out}: {g.shape[0]} x {g.shape[1]} nodes of {g.node_m:g} m in {g.crs}, {filled} with soundings "
          f"({int(result.count.sum())} soundings, up to {int(result.count.max())} a node)")
    for title, counts in (("skipped", result.skipped), ("note", result.notes)):
        for reason, count in counts.items():
            print(f"  {title}: {count} x {reason}")
    return 0


def register(commands, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``lost grid``."""
    grid = commands.add_parser("grid", parents=parents, help="grid the valid soundings of survey files into a CF NetCDF")
    grid.add_argument("files", type=Path, nargs="+", help="survey files of one format, in time order")
    grid.add_argument("--node-m", type=positive_metres, required=True, help="node spacing, metres")
    grid.add_argument("--crs", default=None, help="projected CRS of the grid (default: the UTM zone of the first ping)")
    # Not "out": that name is the run folder's, which a failed command describes; this is one file, written whole.
    grid.add_argument("--out", dest="grid_out", type=Path, required=True, help="the NetCDF file to write (.nc), written whole or not at all")
    grid.add_argument("--replace", action="store_true", help="write over an existing file")
    grid.set_defaults(handler=_cmd_grid)
