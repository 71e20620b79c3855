"""The UTC time of day as NMEA 0183 sentences write it (``hhmmss.ss...``): one formatter for the GNSS's sentences and the USBLs'."""

from __future__ import annotations

import datetime as dt

__all__ = ["nmea_clock"]


def nmea_clock(time_s: float, decimals: int) -> tuple[dt.datetime, str]:
    """The UTC moment of POSIX ``time_s`` rounded to ``decimals`` of a second, and its time of day as ``hhmmss.s...``.

    The moment is rounded first, so a time just before midnight that rounds up is written ``000000.0...`` with the next
    day's date (the moment's, which a ZDA sentence carries).
    """
    moment = dt.datetime.fromtimestamp(round(time_s, decimals), dt.UTC)
    fraction = f"{moment.microsecond / 1e6:.{decimals}f}"[1:] if decimals > 0 else ""
    return moment, moment.strftime("%H%M%S") + fraction
