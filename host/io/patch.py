"""A sonar patch from a file (``lost correlate --patch``): a 2-D array of depths in metres, NaN where no beam landed.

=================  ==========================================================================
file               how it is read
=================  ==========================================================================
``.csv .txt``      one patch row per line, cells separated by commas, semicolons, tabs or
                   spaces (the first data line decides); ``#`` comment lines; an empty cell or
                   ``nan`` is a node without a beam. Any other text in a cell is refused with
                   its line and column, and so is a row of another length than the first.
``.npy``           a 2-D NumPy array of real numbers.
``.npz``           the array ``depth_m`` (or the archive's only array).
=================  ==========================================================================

Complex, text or object arrays are refused by name before any arithmetic sees them.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np

__all__ = ["read_patch", "PATCH_SUFFIXES"]

PATCH_SUFFIXES = (".csv", ".txt", ".npy", ".npz")
_NO_BEAM = ("", "nan", "na", "n/a", "null")


def read_patch(path: str | os.PathLike) -> np.ndarray:
    """The patch in ``path`` as a float64 2-D array (see the module for the formats and what is refused)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no patch file at {path}")
    suffix = path.suffix.lower()
    if suffix == ".npy":
        patch = np.load(path, allow_pickle=False)
    elif suffix == ".npz":
        with np.load(path, allow_pickle=False) as data:
            key = "depth_m" if "depth_m" in data.files else data.files[0] if len(data.files) == 1 else None
            if key is None:
                raise ValueError(f"{path.name} holds {data.files}; name the patch array 'depth_m'")
            patch = data[key]
    elif suffix in (".csv", ".txt"):
        patch = _read_text(path)
    else:
        raise ValueError(f"a patch must be {', '.join(PATCH_SUFFIXES)} of depths in metres, got {path.name}")
    return _checked(np.asarray(patch), path)


def _checked(patch: np.ndarray, path: Path) -> np.ndarray:
    if np.iscomplexobj(patch):
        raise ValueError(f"{path.name} holds complex numbers ({patch.dtype}); a patch holds real depths in metres")
    if not (np.issubdtype(patch.dtype, np.floating) or np.issubdtype(patch.dtype, np.integer)):
        raise ValueError(f"{path.name} holds {patch.dtype} values, not numbers; a patch holds depths in metres")
    if patch.ndim != 2 or min(patch.shape) < 1:
        raise ValueError(f"{path.name} holds an array of shape {patch.shape}; a patch is 2-D, rows by columns")
    return patch.astype(np.float64)


def _read_text(path: Path) -> np.ndarray:
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise ValueError(f"{path.name} is not UTF-8 text (byte {error.start}); a patch CSV is text") from None
    rows: list[list[float]] = []
    split = None
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        if split is None:
            split = _splitter(line)
        cells = split(line)
        if rows and len(cells) != len(rows[0]):
            raise ValueError(f"{path.name}: line {number} has {len(cells)} cells where the first row has {len(rows[0])}: {line.strip()[:80]!r}")
        rows.append([_cell(cell, path, number, column) for column, cell in enumerate(cells, start=1)])
    if not rows:
        raise ValueError(f"{path.name} holds no patch rows")
    return np.array(rows)


def _splitter(line: str):
    for sep in (",", ";", "\t"):
        if sep in line:
            return lambda text, sep=sep: [cell.strip() for cell in text.split(sep)]
    return lambda text: re.split(r"\s+", text.strip())


def _cell(cell: str, path: Path, line: int, column: int) -> float:
    if cell.lower() in _NO_BEAM:
        return np.nan
    try:
        return float(cell)
    except ValueError:
        raise ValueError(
            f"{path.name}: line {line}, column {column} is {cell!r}, not a depth; leave the cell empty (or nan) where no beam landed"
        ) from None
