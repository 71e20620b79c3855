"""The sonar side file of a navigation log: soundings matched to records and gridded into patches."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..records import SonarPatch, SoundingArrays
from .csvtable import _Lines, _numeric, _read_table, _seconds, _where
from .filecheck import DEEPEST_M
from .navlog_checks import SOUNDING_ABOVE_SURFACE_M
from .sonar import grid_soundings, soundings_centre


def _read_sonar(path: Path, *, record_times, epoch, convergence_deg, kept_rows, rows, patch_shape, node_m, time_tolerance_s,
                patch_centre, centre_east, centre_north, age_s=None):
    table = _read_table(path)
    columns = {c.strip().lower(): c for c in table.columns}
    # Soundings are keyed the way the log keeps time (or by record index, which works with either).
    time_key = "t_s" if epoch is None else "time_utc"
    missing = [c for c in ("east_m", "north_m", "depth_m") if c not in columns]
    if time_key not in columns and "record" not in columns:
        other = "time_utc" if time_key == "t_s" else "t_s"
        also = f" ({other} cannot be matched: the log's time is {time_key})" if other in columns else ""
        missing.insert(0, f"{time_key} or record{also}")
    if missing:
        raise ValueError(f"{path.name} lacks the sonar column(s) {', '.join(missing)}; it has {', '.join(table.columns)}")
    key = "record" if "record" in columns else time_key
    lines = _Lines(path, len(table))
    v = {c: _numeric(table[columns[c]], c, path, lines) for c in (key, "east_m", "north_m", "depth_m") if c != "time_utc"}
    if key == "time_utc":
        v["t_s"], _ = _seconds(table[columns["time_utc"]], "time_utc", path, lines, epoch=epoch)
        key = "t_s"
    finite = np.isfinite(v[key]) & np.isfinite(v["east_m"]) & np.isfinite(v["north_m"]) & np.isfinite(v["depth_m"])
    # A sounding above the surface or deeper than any sea is no sounding: counted, not gridded.
    implausible = finite & ((v["depth_m"] < -SOUNDING_ABOVE_SURFACE_M) | (v["depth_m"] > DEEPEST_M))
    finite &= ~implausible

    owner = _owners(v, key, finite, record_times, kept_rows, rows, time_tolerance_s, path, lines)

    n_records = record_times.size
    patches: list[SonarPatch | None] = [None] * n_records
    used = outside = 0
    usable = finite & (owner >= 0)
    order = np.argsort(owner[usable], kind="stable")
    idx = np.flatnonzero(usable)[order]
    owners = owner[idx]
    bounds = np.flatnonzero(np.diff(owners)) + 1
    for group in np.split(idx, bounds) if idx.size else []:
        # Offsets logged beside lat/lon are true east/north: turn them to grid axes like the velocities.
        record = int(owner[group[0]])
        gamma = np.radians(convergence_deg[record])

        def to_grid(east, north, gamma=gamma):
            if not gamma:
                return east, north
            return east * np.cos(gamma) + north * np.sin(gamma), -east * np.sin(gamma) + north * np.cos(gamma)

        east, north = to_grid(v["east_m"][group], v["north_m"][group])
        if centre_east is not None and np.isfinite(centre_east[record]) and np.isfinite(centre_north[record]):
            centre = to_grid(centre_east[record], centre_north[record])
        elif patch_centre == "soundings":
            centre = soundings_centre(east, north)
        else:
            centre = (0.0, 0.0)
        age = float(age_s[record]) if age_s is not None and np.isfinite(age_s[record]) else 0.0
        depth = v["depth_m"][group]
        # The patch carries its soundings: the filters grid them again on lattices moved by fractions of a node.
        held = SoundingArrays(np.asarray(east, float), np.asarray(north, float), np.asarray(depth, float), np.full(len(depth), age))
        gridded = grid_soundings(east, north, depth, patch_shape=patch_shape, node_m=node_m, centre_m=centre, age_s=age, soundings=held)
        used += gridded.used
        outside += gridded.outside
        if gridded.used:
            patches[record] = gridded.patch
    stats = dict(
        sonar_path=str(path),
        soundings=len(table),
        soundings_used=used,
        soundings_without_value=int((~finite).sum()) - int(implausible.sum()),
        soundings_implausible=int(implausible.sum()),
        soundings_unmatched=int((finite & (owner == -1)).sum()),
        soundings_of_skipped_records=int((finite & (owner == -2)).sum()),
        soundings_outside_patch=outside,
        records_with_sonar=sum(p is not None for p in patches),
    )
    assert used + outside + sum(stats[k] for k in ("soundings_without_value", "soundings_implausible", "soundings_unmatched",
                                                   "soundings_of_skipped_records")) == len(table)
    return tuple(patches), stats


def _owners(v, key, finite, record_times, kept_rows, rows, time_tolerance_s, path, lines) -> np.ndarray:
    """Which kept record (index into ``record_times``) each sounding belongs to; -1 none, -2 a skipped row."""
    owner = np.full(len(finite), -1, dtype=np.int64)
    if key == "record":
        index = v["record"]
        whole = finite & (index == np.round(index))
        if np.any(finite & ~whole):
            r = int(np.flatnonzero(finite & ~whole)[0])
            raise ValueError(f"{path.name}: record must be a whole data-row index, got {index[r]} at {_where(r, lines)}")
        position_of_row = np.full(rows, -2, dtype=np.int64)
        position_of_row[kept_rows] = np.arange(kept_rows.size)
        valid_index = whole & (index >= 0) & (index < rows)
        owner[valid_index] = position_of_row[index[valid_index].astype(np.int64)]
    elif record_times.size:
        t = np.where(finite, v["t_s"], np.inf)
        # The nearest record time on either side of each sounding's time.
        after = np.clip(np.searchsorted(record_times, t), 0, record_times.size - 1)
        before = np.clip(after - 1, 0, record_times.size - 1)
        nearest = np.where(np.abs(t - record_times[before]) <= np.abs(t - record_times[after]), before, after)
        matched = finite & (np.abs(t - record_times[nearest]) <= time_tolerance_s)
        owner[matched] = nearest[matched]
    return owner


# --------------------------------------------------------------------------------------------
# plausibility

#: A sounding more than this far above the sea surface (a negative depth) is not of the sea floor (drying banks are a few metres).
