"""What is inside survey files (``lost survey``): format, pings, beams, valid soundings, time span, extent, depths, skips."""

from __future__ import annotations

import datetime as dt
import math
import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from .survey import Survey

__all__ = ["summarize_survey", "format_summary"]


def summarize_survey(paths: str | os.PathLike | Iterable[str | os.PathLike], *, crs: str | None = None) -> dict:
    """One file's (or one format's files') contents as a JSON-ready dict.

    Keys: ``files``, ``format``, ``crs``, ``pings``, ``beams_per_ping`` (sorted distinct counts),
    ``soundings``, ``valid_soundings``, ``time_start_utc``/``time_end_utc`` (ISO 8601) and ``duration_s``,
    ``extent`` (``west``/``south``/``east``/``north``, degrees, of the valid soundings' positions), ``depth_m``
    (``min``/``max`` of the valid soundings), ``skipped`` and ``notes`` (reason -> count). Pings
    without a valid sounding count in ``pings``; the extent and depths are None when no sounding is valid.
    """
    survey = Survey(paths, crs=crs)
    pings = soundings = valid = 0
    beams: set[int] = set()
    t_first, t_last = math.inf, -math.inf
    lo = np.array([math.inf, math.inf])
    hi = -lo
    depth_lo, depth_hi = math.inf, -math.inf
    to_geographic = None
    for ping in survey:
        pings += 1
        beams.add(ping.beams)
        soundings += ping.beams
        valid += int(ping.valid.sum())
        t_first, t_last = min(t_first, ping.time_s), max(t_last, ping.time_s)
        if not ping.valid.any():
            continue
        if to_geographic is None:
            from .crs import transformer

            to_geographic = transformer(survey.crs, "EPSG:4326")
        lon, lat = to_geographic.transform(ping.beam_east_m[ping.valid], ping.beam_north_m[ping.valid])
        lo = np.minimum(lo, [np.min(lon), np.min(lat)])
        hi = np.maximum(hi, [np.max(lon), np.max(lat)])
        depth_lo = min(depth_lo, float(ping.depth_m[ping.valid].min()))
        depth_hi = max(depth_hi, float(ping.depth_m[ping.valid].max()))
    return {
        "files": [str(p) for p in survey.paths],
        "format": survey.format,
        "crs": survey.crs,
        "pings": pings,
        "beams_per_ping": sorted(beams),
        "soundings": soundings,
        "valid_soundings": valid,
        "time_start_utc": _iso(t_first) if pings else None,
        "time_end_utc": _iso(t_last) if pings else None,
        "duration_s": round(t_last - t_first, 3) if pings else None,
        "extent": ({"west": float(lo[0]), "south": float(lo[1]), "east": float(hi[0]), "north": float(hi[1])} if valid else None),
        "depth_m": ({"min": depth_lo, "max": depth_hi} if valid else None),
        "skipped": dict(survey.skipped),
        "notes": dict(survey.notes),
    }


def _iso(t: float) -> str:
    return dt.datetime.fromtimestamp(t, dt.UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def format_summary(summary: dict) -> str:
    """The summary as lines of text for a terminal."""
    lines = [f"{', '.join(Path(f).name for f in summary['files'])}: {summary['format']}"]
    lines.append(f"  pings {summary['pings']}, beams per ping {', '.join(map(str, summary['beams_per_ping'])) or '-'}, "
                 f"valid soundings {summary['valid_soundings']} of {summary['soundings']}")
    if summary["pings"]:
        lines.append(f"  time {summary['time_start_utc']} to {summary['time_end_utc']} ({summary['duration_s']:g} s)")
    if summary["extent"]:
        e, d = summary["extent"], summary["depth_m"]
        lines.append(f"  extent lon {e['west']:.5f} to {e['east']:.5f}, lat {e['south']:.5f} to {e['north']:.5f}")
        lines.append(f"  depth {d['min']:.2f} to {d['max']:.2f} m, projected in {summary['crs']}")
    for title, counts in (("skipped", summary["skipped"]), ("notes", summary["notes"])):
        for reason, count in counts.items():
            lines.append(f"  {title}: {count} x {reason}")
    return "\n".join(lines)
