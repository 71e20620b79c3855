"""ASCII soundings (``x y z`` or ``lon lat z``) read and gridded into a :class:`~lost.host.grid.Grid`."""

from __future__ import annotations

import logging
import re
from pathlib import Path

import numpy as np

from ..grid import Grid
from .crs import GEOGRAPHIC_NAMES, X_NAMES, Y_NAMES, _same_crs, _target_crs, as_crs, transformer
from .depthsign import _sign_from_metadata, _to_depth
from .gridding import _grid_soundings, _lattice, _regular_to_grid

log = logging.getLogger(__name__)

_Z_NAMES = ("z", "depth", "depth_m", "elevation", "elevation_m", "height", "altitude", "topo", "bathymetry")


def _read_xyz(path: Path, *, crs, node_m, source_crs, positive, max_gap_m, bounds, nodata) -> Grid:
    import pandas as pd

    first = _first_data_line(path)
    sep = "," if "," in first else ";" if ";" in first else r"\s+"
    tokens = [t for t in re.split(r"[\s,;]+", first.strip()) if t]
    has_header = not all(_is_number(t) for t in tokens)
    try:
        table = pd.read_csv(path, sep=sep, comment="#", header=0 if has_header else None, skip_blank_lines=True)
    except pd.errors.ParserError as error:
        raise ValueError(f"{path.name}: {_stray_line(path, str(error))}") from None
    if has_header:
        columns = {str(c).strip().lower(): c for c in table.columns}
        picked = []
        for role, names in (("x", X_NAMES), ("y", Y_NAMES), ("z", _Z_NAMES)):
            name = next((columns[n] for n in names if n in columns), None)
            if name is None:
                raise ValueError(
                    f"{path.name}: no {role} column; expected one of {', '.join(names)}, found {', '.join(map(str, table.columns))}"
                )
            picked.append(name)
        x_col, y_col, z_col = picked
        geographic = str(x_col).strip().lower() in GEOGRAPHIC_NAMES
        sign_hint = _sign_from_metadata({}, str(z_col))
    else:
        if table.shape[1] != 3:
            raise ValueError(f"{path.name}: a headerless XYZ file has 3 columns (x y z), this one has {table.shape[1]}")
        x_col, y_col, z_col = table.columns
        geographic = None
        sign_hint = None
    try:
        x, y, z = (pd.to_numeric(table[c], errors="raise").to_numpy(np.float64) for c in (x_col, y_col, z_col))
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{path.name}: a non-numeric value in the x, y, z columns ({exc})") from None
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        bad = int(np.flatnonzero(~(np.isfinite(x) & np.isfinite(y)))[0])
        raise ValueError(f"{path.name}: sounding {bad + 1} has no position (NaN or empty x/y)")
    if bounds is not None:
        inside = (x >= bounds[0]) & (x <= bounds[2]) & (y >= bounds[1]) & (y <= bounds[3])
        x, y, z = x[inside], y[inside], z[inside]
    keep = np.isfinite(z)
    if not keep.all():
        log.warning("%s: skipped %d of %d soundings with no depth (NaN)", path.name, int((~keep).sum()), z.size)
        x, y, z = x[keep], y[keep], z[keep]
    if z.size < 3:
        raise ValueError(f"{path.name}: {z.size} sounding(s) with a depth; gridding needs at least 3")

    if source_crs is not None:
        if geographic is not None and geographic != as_crs(source_crs).is_geographic:
            raise ValueError(f"{path.name}: the column names say {'lon/lat' if geographic else 'x/y'}, source_crs says {source_crs}")
        file_crs = as_crs(source_crs).to_string()
    elif geographic:
        file_crs = "EPSG:4326"
    elif geographic is None and np.all(np.abs(x) <= 360) and np.all(np.abs(y) <= 90):
        raise ValueError(
            f"{path.name}: a headerless file whose coordinates could be longitude/latitude or metres; "
            "name the columns (lon lat z / x y z) or pass source_crs="
        )
    else:
        file_crs = None
    z = _to_depth(z, positive or sign_hint, path.name, f"column {z_col!r}" if has_header else "the third (z) column", nodata)
    keep = np.isfinite(z)  # nodata made holes: a hole is the absence of a sounding
    x, y, z = x[keep], y[keep], z[keep]
    lattice = _lattice(x, y, z) if max_gap_m is None else None
    if lattice is not None:
        # Gridded soundings (grd2xyz): read node for node, so a missing node stays a hole, exactly, and
        # nothing lies past the data's edge. (An explicit max_gap_m asks for the triangulation's bridging.)
        return _regular_to_grid(*lattice, file_crs, crs=crs, node_m=node_m)

    target = _target_crs(file_crs, crs, x, y)
    if file_crs is not None and target is not None and not _same_crs(file_crs, target):
        x, y = transformer(file_crs, target).transform(x, y)
        x, y = np.asarray(x), np.asarray(y)
    return _grid_soundings(x, y, z, node_m=node_m, max_gap_m=max_gap_m, crs=target, name=path.name)


def _first_data_line(path: Path) -> str:
    with path.open("r", encoding="utf-8", errors="replace") as f:
        for line in f:
            if line.strip() and not line.lstrip().startswith("#"):
                return line
    raise ValueError(f"{path.name} holds no data lines")


def _is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def _stray_line(path: Path, reason: str) -> str:
    """pandas' "Expected 3 fields in line 302, saw 4" (a file line number) with that line's text."""
    match = re.search(r"Expected (\d+) fields in line (\d+), saw (\d+)", reason)
    if match is None:
        return f"not a table of soundings ({' '.join(reason.split())})"
    expected, number, seen = (int(g) for g in match.groups())
    with path.open("r", encoding="utf-8", errors="replace") as f:
        for k, line in enumerate(f, start=1):
            if k == number:
                return f"line {number} has {seen} fields where the lines before it have {expected}: {line.strip()[:80]!r}"
    return f"line {number} has {seen} fields where the lines before it have {expected}"
