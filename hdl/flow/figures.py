"""The FPGA figures as data: one CSV row per placed build, appended by the flow, kept in the repository.

Every configuration :mod:`lost.hdl.flow.synth` builds appends a row to ``docs/fpga_figures.csv``
(:data:`FIGURES_PATH`): the gateware commit it was built from, the configuration, the best seed's
post-route Fmax, LUT4, FF, EBR and DSP, the cycles and time of one correlation, and how long place and
route took. So a regression shows as a row, as coreblocks tracks its builds. The table in
``docs/fpga.md`` is generated from the file (``python -m lost.hdl.flow.figures --update docs/fpga.md``:
the latest row of each configuration, between the page's ``figures`` markers).

The gateware commit is ``git rev-parse --short HEAD``, with ``+dirty`` when ``hdl/`` has changes not
committed: a figure measured on uncommitted gateware says so.
"""

from __future__ import annotations

import argparse
import csv
import datetime
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

__all__ = ["FIELDS", "FIGURES_PATH", "append", "gateware_commit", "latest", "markdown_table", "read", "recorded", "row_of",
           "update_page"]

#: The repository's checkout (the folder holding ``hdl/``).
CHECKOUT = Path(__file__).resolve().parents[2]
FIGURES_PATH = CHECKOUT / "docs" / "fpga_figures.csv"

#: The columns, in order. ``route_seconds`` is empty for rows imported from an earlier report.
FIELDS = ("date", "commit", "name", "variant", "lanes", "memory", "map", "patch", "lut_mapper", "router", "seed",
          "target_mhz", "fmax_mhz", "lut4", "ff", "ebr", "dsp", "lut4_available", "cycles", "correlation_ms",
          "route_seconds", "note")

BEGIN, END = "<!-- figures:begin -->", "<!-- figures:end -->"


def gateware_commit(checkout: Path = CHECKOUT) -> str:
    """The short commit of ``checkout``'s HEAD, ``+dirty`` if ``hdl/`` differs from it; ``unknown`` outside git."""
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=checkout, capture_output=True, text=True,
                              check=True).stdout.strip()
        changed = subprocess.run(["git", "status", "--porcelain", "--", "hdl"], cwd=checkout, capture_output=True,
                                 text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+dirty" if changed else "")


def row_of(entry: dict, *, commit: str, date: str | None = None) -> dict:
    """The CSV row of one routed entry of the flow's report (``routed`` true).

    Raises
    ------
    ValueError
        The entry was not placed and routed (it has no post-route figures).
    """
    if not entry.get("routed"):
        raise ValueError(f"{entry.get('name', 'the entry')} was not placed and routed; it has no figures to record")
    result = entry["result"]
    return {
        "date": date or datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d"),
        "commit": commit,
        "name": entry["name"],
        "variant": entry["variant"],
        "lanes": entry["lanes"],
        "memory": entry["memory"],
        "map": "x".join(map(str, entry["map_shape"])),
        "patch": "x".join(map(str, entry["patch_shape"])),
        "lut_mapper": entry.get("lut_mapper", "abc9"),
        "router": entry.get("router", ""),
        "seed": result["seed"],
        "target_mhz": result["target_mhz"],
        "fmax_mhz": round(result["fmax_mhz"], 2),
        "lut4": result["lut4"],
        "ff": result["ff"],
        "ebr": result["ebr"],
        "dsp": result["dsp"],
        "lut4_available": result["lut4_available"],
        "cycles": entry["cycles"],
        "correlation_ms": round(entry["seconds"] * 1e3, 3),
        "route_seconds": result.get("seconds", ""),
        "note": "",
    }


def recorded(rows: Sequence[dict], row: dict) -> bool:
    """Whether ``rows`` already hold this build's figures (same name, commit, seed and Fmax): a rerun of the
    flow over cached results adds nothing."""
    key = (row["name"], row["commit"], str(row["seed"]), f"{float(row['fmax_mhz']):.2f}")
    return any((r["name"], r["commit"], str(r["seed"]), f"{float(r['fmax_mhz']):.2f}") == key for r in rows)


def read(path: Path = FIGURES_PATH) -> list[dict]:
    """Every row of the figures file, oldest first.

    Raises
    ------
    ValueError
        The file's header is not :data:`FIELDS` (the row and file are named).
    """
    path = Path(path)
    if not path.exists():
        return []
    with path.open(newline="") as f:
        reader = csv.DictReader(f)
        if tuple(reader.fieldnames or ()) != FIELDS:
            raise ValueError(f"{path}: the header is {reader.fieldnames}, expected {list(FIELDS)}")
        return list(reader)


def append(row: dict, path: Path = FIGURES_PATH) -> None:
    """Append ``row`` (every field of :data:`FIELDS`) to the figures file, writing its header if new."""
    missing = [field for field in FIELDS if field not in row]
    if missing:
        raise ValueError(f"a figures row needs every field; missing {missing}")
    path = Path(path)
    new = not path.exists()
    if not new:
        read(path)  # refuses a file with another header before adding to it
    with path.open("a", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=FIELDS, lineterminator="\n")
        if new:
            writer.writeheader()
        writer.writerow({field: row[field] for field in FIELDS})


def latest(rows: Sequence[dict]) -> list[dict]:
    """The last row of each configuration name, in the order each name first appeared."""
    last = {row["name"]: row for row in rows}
    return [last[name] for name in dict.fromkeys(row["name"] for row in rows)]


def markdown_table(rows: Sequence[dict]) -> str:
    """The page's table: one line per row given."""
    lines = [
        "| variant | lanes | map | memory | Fmax (MHz) | LUT4 | FF | EBR | DSP | cycles | time | gateware | date | mapper |",
        "|---|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|---|",
    ]
    for row in rows:
        percent = 100 * int(row["lut4"]) / int(row["lut4_available"])
        lines.append(
            f"| {row['variant']} | {row['lanes']} | {row['map']} | {row['memory']} | {float(row['fmax_mhz']):.1f} "
            f"| {int(row['lut4'])} ({percent:.0f} %) | {row['ff']} | {row['ebr']} | {row['dsp']} | {int(row['cycles']):,} "
            f"| {float(row['correlation_ms']):.3f} ms | {row['commit']} | {row['date']} | {row['lut_mapper']} |")
    return "\n".join(lines) + "\n"


def update_page(page: Path, rows: Sequence[dict]) -> None:
    """Replace the table between the page's ``figures`` markers with that of the latest row of each build."""
    page = Path(page)
    text = page.read_text()
    if BEGIN not in text or END not in text:
        raise ValueError(f"{page} has no {BEGIN} ... {END} markers to put the table between")
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    page.write_text(f"{head}{BEGIN}\n{markdown_table(latest(rows))}{END}{tail}")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m lost.hdl.flow.figures", description=__doc__.splitlines()[0])
    parser.add_argument("--figures", type=Path, default=FIGURES_PATH, help="the CSV (docs/fpga_figures.csv)")
    parser.add_argument("--update", type=Path, metavar="PAGE", help="rewrite the table between PAGE's figures markers")
    parser.add_argument("--all", action="store_true", help="print every row, not only the latest of each build")
    args = parser.parse_args(argv)
    try:
        rows = read(args.figures)
        if args.update:
            update_page(args.update, rows)
    except ValueError as error:
        parser.error(str(error))
    print(markdown_table(rows if args.all else latest(rows)), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
