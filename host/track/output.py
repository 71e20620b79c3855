"""What ``lost track`` writes into its run folder besides the summary: ``tracks.csv`` and the table of tracks.

The folder itself is written whole or not at all (``lost.host.runfolder``); ``tracks.csv`` is also written under a
temporary name and moved into place, so a reader never sees half of it.
"""

from __future__ import annotations

import csv
import math
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

from ..runfolder import atomic_write
from .tracker import TrackReport

__all__ = ["TRACK_COLUMNS", "write_tracks_csv", "track_table"]

TRACK_COLUMNS = ("ping", "t_s", "track_id", "status", "existence", "x_m", "y_m", "vx_mps", "vy_mps", "sd_x_m", "sd_y_m", "speed_mps",
                 "heading_deg", "range_m", "bearing_deg", "class", "cpa_m", "t_cpa_s", "time_to_reach_s")


def _cell(value: float) -> str:
    return "" if isinstance(value, float) and math.isnan(value) else f"{value:.3f}" if isinstance(value, float) else str(value)


def write_tracks_csv(path: Path, reports: Sequence[Sequence[TrackReport]]) -> Path:
    """One row per ping and live track (status tentative, confirmed, or outside the sector; its existence probability); empty cells where a figure is undefined
    (``time_to_reach_s`` when the track passes wide of the sonar)."""
    def write(handle) -> None:
        writer = csv.writer(handle)
        writer.writerow(TRACK_COLUMNS)
        for ping in reports:
            for r in ping:
                writer.writerow([r.ping, _cell(r.t_s), r.track_id, r.status, f"{r.existence:.6f}", *(_cell(v) for v in (
                    r.x_m, r.y_m, r.vx_mps, r.vy_mps, r.sd_x_m, r.sd_y_m, r.speed_mps, r.heading_deg, r.range_m, r.bearing_deg)),
                    r.classification, _cell(r.cpa_m), _cell(r.t_cpa_s), _cell(r.time_to_reach_s)])
    return atomic_write(path, write)


def track_table(reports: Sequence[Sequence[TrackReport]]) -> list[dict]:
    """Each confirmed track once: its pings, its most frequent class, and its last speed, CPA and time to reach."""
    seen: dict[int, list[TrackReport]] = {}
    for ping in reports:
        for r in ping:
            if r.status == "confirmed":
                seen.setdefault(r.track_id, []).append(r)
    table = []
    for track_id, rows in sorted(seen.items()):
        last = rows[-1]
        classes = Counter(r.classification for r in rows if r.classification != "unknown")
        table.append({
            "track_id": track_id, "first_ping": rows[0].ping, "last_ping": last.ping, "pings": len(rows),
            "class": classes.most_common(1)[0][0] if classes else "unknown",
            "last_speed_mps": round(last.speed_mps, 3), "last_range_m": round(last.range_m, 1), "last_cpa_m": round(last.cpa_m, 1),
            "last_time_to_reach_s": None if math.isnan(last.time_to_reach_s) else round(last.time_to_reach_s, 1),
        })
    return table
