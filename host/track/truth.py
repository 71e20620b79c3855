"""Where the targets really were: a truth CSV beside a detection log (a diver's GPS float, a simulation).

One row per fix, a header, ``#`` comments allowed, names matched case- and space-blind:

==============  ========  ================================================================
column          required  meaning
==============  ========  ================================================================
``target``      yes       target identity (any text); a target's rows in increasing time
``t_s``         yes       time of the fix, seconds, the detection log's clock
``x_m``         yes       east, metres, the detection log's frame
``y_m``         yes       north, metres
``kind``        no        diver, drifting or animal (default diver)
==============  ========  ================================================================

Each target's track is interpolated linearly to the pings' times within its first and last fix (NaN
outside: not in the water as far as the truth knows); its velocity is the slope between the fixes around
each ping. A target counts as seen at a ping when it lies in the sonar's sector. Errors (``ValueError``
naming the file, line and column): a missing column, a non-number, a target's time not increasing.
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .detections import Ping
from .geometry import Sonar, world_to_polar
from .simulate import TARGET_KINDS, Truth

__all__ = ["read_truth", "write_truth", "TRUTH_COLUMNS"]

TRUTH_COLUMNS = ("target", "t_s", "x_m", "y_m", "kind")


def _fixes(path: Path) -> dict[str, tuple[list[tuple[float, float, float]], str]]:
    targets: dict[str, tuple[list[tuple[float, float, float]], str]] = {}
    with path.open(newline="") as handle:
        rows = (line for line in csv.reader(handle) if line and not line[0].lstrip().startswith("#"))
        header = [name.strip().lower() for name in next(rows, [])]
        missing = [name for name in TRUTH_COLUMNS[:4] if name not in header]
        if missing:
            raise ValueError(f"{path} lacks the truth column(s) {', '.join(missing)} (layout: lost.host.track.truth)")
        index = {name: header.index(name) for name in TRUTH_COLUMNS if name in header}
        for number, line in enumerate(rows, start=1):
            where = f"{path}, data row {number}"
            cell = {name: (line[i].strip() if i < len(line) else "") for name, i in index.items()}
            values = []
            for name in ("t_s", "x_m", "y_m"):
                try:
                    values.append(float(cell[name]))
                except ValueError:
                    raise ValueError(f"{where}: {name} is not a number: {cell[name]!r}") from None
                if not math.isfinite(values[-1]):
                    raise ValueError(f"{where}: {name} must be finite, got {cell[name]!r}")
            kind = cell.get("kind") or "diver"
            if kind not in TARGET_KINDS:
                raise ValueError(f"{where}: kind must be one of {TARGET_KINDS}, got {kind!r}")
            fixes, _ = targets.setdefault(cell["target"], ([], kind))
            if fixes and values[0] <= fixes[-1][0]:
                raise ValueError(f"{where}: t_s {values[0]!r} of target {cell['target']!r} does not increase on {fixes[-1][0]!r}")
            fixes.append(tuple(values))
    if not targets:
        raise ValueError(f"{path} holds no truth fix")
    return targets


def read_truth(path: str | os.PathLike, pings: Sequence[Ping], *, sonar: Sonar | None = None) -> Truth:
    """Read a truth CSV (module docstring) and put it on the pings' times: a :class:`Truth` to score against."""
    path, sonar = Path(path), sonar or Sonar()
    targets = _fixes(path)
    t = np.array([p.t_s for p in pings])
    xy = np.full((t.size, len(targets), 2), np.nan)
    velocity = np.full_like(xy, np.nan)
    for k, (fixes, _) in enumerate(targets.values()):
        f = np.array(fixes)
        inside = (t >= f[0, 0]) & (t <= f[-1, 0])
        for axis in (0, 1):
            xy[inside, k, axis] = np.interp(t[inside], f[:, 0], f[:, axis + 1])
            if len(f) > 1:
                slopes = np.diff(f[:, axis + 1]) / np.diff(f[:, 0])
                segment = np.clip(np.searchsorted(f[:, 0], t[inside], side="right") - 1, 0, len(f) - 2)
                velocity[inside, k, axis] = slopes[segment]
    in_sector = np.zeros(xy.shape[:2], dtype=bool)
    for i, ping in enumerate(pings):
        alive = np.isfinite(xy[i, :, 0])
        if alive.any():
            r, b = world_to_polar(ping.platform_xy, ping.heading_deg, xy[i, alive])
            in_sector[i, alive] = sonar.inside(r, b)
    return Truth(t, xy, velocity, tuple(kind for _, kind in targets.values()), in_sector)


def write_truth(path: str | os.PathLike, truth: Truth) -> Path:
    """Write a simulation's truth in the layout :func:`read_truth` reads (one fix per ping and live target)."""
    path = Path(path)
    with path.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(TRUTH_COLUMNS)
        for k, kind in enumerate(truth.kinds):
            for i in np.flatnonzero(np.isfinite(truth.xy[:, k, 0])):
                writer.writerow([k, repr(float(truth.t_s[i])), repr(float(truth.xy[i, k, 0])), repr(float(truth.xy[i, k, 1])), kind])
    return path
