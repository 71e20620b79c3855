"""Plausibility of a USBL log's replies as a whole, before any fix: units a reader cannot see in one value.

A reply's travel time and its direction must agree with the towfish's logged depth: the straight path the travel
time gives at the water's mean speed, times the cosine of the direction's angle from the vertical, is the depth
below the transducer (within the ray's bending, a few per cent). Over the whole log the median of that ratio is
about 1; about 2 means two-way travel times under the one-way name; about 1000 means milliseconds. Direction
cosines beyond 1 for most replies mean phases (or cosines) in degrees, or a wrong baseline or frequency.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .fix import UsblArray, direction_cosines_from_phase
from .sound import SoundSpeedProfile

__all__ = ["UsblLogError", "check_replies"]


class UsblLogError(ValueError):
    """A USBL log whose replies as a whole are implausible (a unit, a column meaning); the message names the log."""


def check_replies(log: pd.DataFrame, profile: SoundSpeedProfile, array: UsblArray) -> None:
    """Refuse a log whose directions or travel times are in the wrong unit or meaning (see the module docstring).

    Raises
    ------
    UsblLogError
        Most replies give no downward direction, or the travel times are milliseconds or two-way; the message
        names the log, the columns, the evidence and the fix.
    """
    source = log.attrs.get("source", "USBL log")
    travel = log["travel_time_s"].to_numpy(dtype=float)
    replied = np.isfinite(travel)
    if not replied.any():
        return
    first, second = log.attrs.get("direction_columns", ("phase_x_rad", "phase_y_rad"))
    raw = log.loc[replied, [first, second]].to_numpy(dtype=float)
    top = max(array.lever_arm_m[2] - array.antenna_height_m, 0.0)
    if first == "phase_x_rad":
        wavelength = array.wavelength_m(float(profile.speed_at(top)))
        cosines = direction_cosines_from_phase(raw, wavelength, array.baseline_m)
        in_degrees = direction_cosines_from_phase(np.radians(raw), wavelength, array.baseline_m)
    else:
        cosines, in_degrees = raw, np.radians(raw)
    horizontal = np.sum(cosines**2, axis=1)
    upward = horizontal >= 1.0
    if upward.mean() > 0.5:
        example = int(np.flatnonzero(replied)[np.flatnonzero(upward)[0]])
        hint = ("the values look like degrees (as degrees they give a downward direction for "
                f"{np.mean(np.sum(in_degrees**2, axis=1) < 1.0):.0%} of the replies): convert them to radians"
                if np.mean(np.sum(in_degrees**2, axis=1) < 1.0) > 0.9 else
                "check the unit of the columns and the array's baseline_m and frequency_hz in the config")
        raise UsblLogError(f"{source}: {first}, {second} give no downward direction for {int(upward.sum())} of {int(replied.sum())} replies "
                           f"(row {example + 1}: {raw[upward][0][0]:g}, {raw[upward][0][1]:g}); {hint}")
    depth = log.loc[replied, "fish_depth_m"].to_numpy(dtype=float)[~upward] - top
    usable = depth > 1.0
    if not usable.any():
        return
    bottom = min(float(np.median(depth[usable])) + top, profile.bottom_m)
    speed = profile.harmonic_mean_m_s(top, bottom) if bottom > top else float(profile.speed_at(top))
    ratio = speed * travel[replied][~upward][usable] * np.sqrt(1.0 - horizontal[~upward][usable]) / depth[usable]
    median = float(np.median(ratio))
    evidence = (f"the travel time at {speed:.0f} m/s times the cosine of the reply's angle from the vertical is {median:.3g} times the "
                f"towfish's depth below the transducer (median of {ratio.size} replies; about 1 for one-way seconds)")
    if median > 200.0:
        raise UsblLogError(f"{source}: travel_time_s looks like milliseconds: {evidence}; convert the column to seconds")
    if 1.6 <= median <= 2.6:
        raise UsblLogError(f"{source}: travel_time_s looks like two-way travel times: {evidence}; name the column two_way_travel_time_s "
                           "(the transponder's turnaround_s goes in the config's [usbl] table)")
    if not 0.6 <= median <= 1.4:
        raise UsblLogError(f"{source}: travel times and directions disagree with the towfish's depth: {evidence}; check the units of "
                           "travel_time_s, the direction columns and fish_depth_m")
