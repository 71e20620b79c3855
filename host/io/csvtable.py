"""CSV tables of logs and side files: header, separator, cells as numbers or times, each error naming the file line."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np


def _read_table(path: Path):
    import pandas as pd

    if not path.is_file():
        raise FileNotFoundError(f"no file at {path}")
    header = _header_line(path)
    sep = _separator(header)
    _refuse_duplicates([name.strip() for name in header.split(sep)], path)
    try:
        # The C parser makes clean columns float64 at once; a column with a stray word stays text, and
        # _numeric then names the cell. Only these words (and empty cells) are missing readings.
        return pd.read_csv(
            path, sep=sep, comment="#", skipinitialspace=True, keep_default_na=False,
            na_values=["", "nan", "NaN", "NAN", "NA", "n/a", "N/A", "null", "NULL", "NaT"],
        )
    except pd.errors.EmptyDataError:
        raise ValueError(f"{path.name} is empty; a header row naming the columns is needed") from None
    except pd.errors.ParserError as exc:
        raise ValueError(f"{path.name} is not a well-formed CSV: {' '.join(str(exc).split())}") from None
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path.name} is not UTF-8 text (a byte {exc.object[exc.start]:#04x} at {exc.start}); is it a binary file?") from None


def _header_line(path: Path) -> str:
    try:
        with path.open("r", encoding="utf-8") as stream:
            for line in stream:
                if line.strip() and not line.lstrip().startswith("#"):
                    return line.rstrip("\r\n").lstrip("\ufeff")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path.name} is not UTF-8 text (a byte {exc.object[exc.start]:#04x} at {exc.start}); is it a binary file?") from None
    raise ValueError(f"{path.name} is empty; a header row naming the columns is needed")


def _separator(header: str) -> str:
    """Comma, semicolon or tab: whichever separates the header's names (the most frequent of the three)."""
    counts = {sep: header.count(sep) for sep in (",", ";", "\t")}
    best = max(counts, key=counts.get)
    return best if counts[best] else ","


def _refuse_duplicates(names: list[str], path: Path) -> None:
    seen: dict[str, int] = {}
    for index, name in enumerate(names):
        key = name.lower()
        if key in seen:
            raise ValueError(
                f"{path.name}: the column name {name!r} appears twice (columns {seen[key] + 1} and {index + 1}, "
                f"names compared without case: {names[seen[key]]!r}); which one is meant cannot be guessed, rename or drop one"
            )
        seen[key] = index


class _Lines:
    """File line (1-based) of each data row, for error messages; counted only when one is raised."""

    def __init__(self, path: Path, rows: int) -> None:
        self._path, self._rows = path, rows

    @functools.cached_property
    def numbers(self) -> np.ndarray | None:
        numbers = []
        with self._path.open("r", encoding="utf-8", errors="replace") as f:
            for number, line in enumerate(f, start=1):
                if line.strip() and not line.lstrip().startswith("#"):
                    numbers.append(number)
        numbers = numbers[1:]  # the header
        # A quoted cell spanning lines would shift the count: then name the data row only.
        return np.asarray(numbers) if len(numbers) == self._rows else None


def _where(row: int, lines: _Lines) -> str:
    numbers = lines.numbers
    return f"data row {row}" + (f" (line {int(numbers[row])})" if numbers is not None else "")


_MISSING_WORDS = ("nan", "na", "n/a", "null")


def _numeric(column, name: str, path: Path, lines: _Lines) -> np.ndarray:
    import pandas as pd

    if pd.api.types.is_bool_dtype(column.dtype):
        raise ValueError(f"{path.name}: {name} holds true/false, not numbers, from {_where(0, lines)}: {column.iloc[0]!r}")
    if pd.api.types.is_numeric_dtype(column.dtype):
        return column.to_numpy(np.float64)
    number = pd.to_numeric(column, errors="coerce").to_numpy(np.float64)
    # Only cells that did not parse are looked at again: empty or a missing word is a missing reading.
    unparsed = np.flatnonzero(np.isnan(number))
    if unparsed.size:
        text = column.iloc[unparsed].astype(str).str.strip().str.lower()
        bad = unparsed[~(column.iloc[unparsed].isna() | (text == "") | text.isin(_MISSING_WORDS)).to_numpy()]
        if bad.size:
            row = int(bad[0])
            raise ValueError(f"{path.name}: {name} is not a number at {_where(row, lines)}: {column.iloc[row]!r}")
    return number


def _seconds(column, name: str, path: Path, lines, *, epoch):
    """ISO 8601 timestamps to seconds from ``epoch`` (default: the first timestamp); NaN where empty."""
    import pandas as pd

    text = column.astype(str).str.strip()
    empty = column.isna() | (text == "") | text.str.lower().isin(_MISSING_WORDS + ("nat",))
    stamps = pd.to_datetime(text.where(~empty), utc=True, errors="coerce", format="ISO8601")
    bad = np.flatnonzero(stamps.isna().to_numpy() & ~empty.to_numpy())
    if bad.size:
        row = int(bad[0])
        raise ValueError(f"{path.name}: {name} is not an ISO 8601 time at {_where(row, lines)}: {column.iloc[row]!r}")
    if epoch is None:
        known = stamps.dropna()
        if known.empty:
            return np.full(len(stamps), np.nan), None
        epoch = known.iloc[0]
    return (stamps - epoch).dt.total_seconds().to_numpy(np.float64, na_value=np.nan), epoch


def _pick_pair(columns: dict, forms, what: str, notes: list, *, required: bool):
    present = [form for form in forms if all(c in columns for c in form)]
    partial = [c for form in forms for c in form if c in columns and form not in present]
    if partial and not present:
        form = next(f for f in forms if any(c in columns for c in f))
        lacking = [c for c in form if c not in columns]
        raise ValueError(f"the {what} column {', '.join(c for c in form if c in columns)} needs {', '.join(lacking)} too")
    if not present:
        if required:
            alternatives = " or ".join("/".join(form) for form in forms)
            raise ValueError(f"the {what} is missing: the log needs the columns {alternatives}; it has {', '.join(columns.values())}")
        return None
    unread = [c for form in forms if form != present[0] for c in form if c in columns]
    if unread:
        notes.append(f"{'/'.join(present[0])} used for the {what}; {', '.join(unread)} not read")
    return present[0]
