"""The sector plot of the paper's Figure 5 and an animation over the pings (matplotlib, Agg; GIF by Pillow).

Both are drawn in the sonar's own frame at each ping (cross-range to starboard, range ahead), as the paper
draws its sector: blue dots are the search cloud's particles, red dots the ping's detections, dash-dot
curves each confirmed track's history, labelled with its identity and class; green crosses are the true
targets when a simulation knows them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .detections import Ping
from .geometry import Sonar
from .tracker import TrackReport

__all__ = ["plot_sector", "animate", "MAX_FRAMES"]

#: An animation shows at most this many pings (every k-th ping of a longer run), to keep the GIF small.
MAX_FRAMES = 150


def _to_sonar_frame(ping: Ping, xy: np.ndarray) -> np.ndarray:
    """World (n, 2) to the ping's sonar frame: (cross-range to starboard, along the axis)."""
    d = np.asarray(xy, float).reshape(-1, 2) - ping.platform_xy
    h = math.radians(ping.heading_deg)
    return np.column_stack((d[:, 0] * math.cos(h) - d[:, 1] * math.sin(h), d[:, 0] * math.sin(h) + d[:, 1] * math.cos(h)))


def _sector(ax, sonar: Sonar) -> None:
    a = np.radians(np.linspace(-sonar.half_fov_deg, sonar.half_fov_deg, 91))
    r = sonar.max_range_m
    edge = np.concatenate(([[0.0, 0.0]], np.column_stack((r * np.sin(a), r * np.cos(a))), [[0.0, 0.0]]))
    ax.plot(edge[:, 0], edge[:, 1], color="0.4", lw=0.8)
    for ring in (100.0, 200.0, 300.0, 400.0):
        if ring < r:
            ax.plot(ring * np.sin(a), ring * np.cos(a), color="0.85", lw=0.5)
    ax.set_aspect("equal")
    half = r * math.sin(math.radians(min(sonar.half_fov_deg, 90.0)))
    ax.set_xlim(-half - 10, half + 10)
    ax.set_ylim(-10, r + 10)
    ax.set_xlabel("cross-range, starboard (m)")
    ax.set_ylabel("range along the sonar axis (m)")


def _histories(reports: Sequence[Sequence[TrackReport]], upto: int) -> dict[int, list[TrackReport]]:
    tracks: dict[int, list[TrackReport]] = {}
    for ping_reports in reports[: upto + 1]:
        for r in ping_reports:
            if r.status == "confirmed":
                tracks.setdefault(r.track_id, []).append(r)
    return tracks


def _draw(ax, sonar: Sonar, pings: Sequence[Ping], reports, clouds, i: int, truth_xy: np.ndarray | None) -> None:
    ping = pings[i]
    _sector(ax, sonar)
    if clouds is not None and clouds[i].size:
        c = _to_sonar_frame(ping, clouds[i])
        ax.plot(c[:, 0], c[:, 1], ".", color="tab:blue", ms=1.5, alpha=0.5, label="particles")
    if ping.detections:
        d = _to_sonar_frame(ping, ping.detections_xy())
        ax.plot(d[:, 0], d[:, 1], "o", color="red", ms=3.5, label="detections")
    live = {r.track_id for r in reports[i] if r.status == "confirmed"}
    for track_id, history in _histories(reports, i).items():
        if track_id not in live:
            continue
        h = _to_sonar_frame(ping, np.array([[r.x_m, r.y_m] for r in history]))
        ax.plot(h[:, 0], h[:, 1], "-.", color="c", lw=1.5)
        ax.annotate(f"{track_id} {history[-1].classification}", h[-1], textcoords="offset points", xytext=(5, 5), fontsize=7, color="teal")
    if truth_xy is not None:
        alive = np.isfinite(truth_xy[i, :, 0])
        if alive.any():
            t = _to_sonar_frame(ping, truth_xy[i, alive])
            ax.plot(t[:, 0], t[:, 1], "x", color="green", ms=6, label="truth")
    ax.set_title(f"ping {ping.index}, t = {ping.t_s:.1f} s, {len(live)} confirmed track(s)")


def plot_sector(path: Path, sonar: Sonar, pings: Sequence[Ping], reports, clouds, *, ping: int = -1,
                truth_xy: np.ndarray | None = None) -> Path:
    """The paper's Figure 5 at one ping (default the last): particles, detections, track histories."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    i = ping % len(pings)
    fig, ax = plt.subplots(figsize=(7, 5.5))
    _draw(ax, sonar, pings, reports, clouds, i, truth_xy)
    ax.legend(loc="lower right", fontsize=7, markerscale=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def animate(path: Path, sonar: Sonar, pings: Sequence[Ping], reports, clouds, *, truth_xy: np.ndarray | None = None, fps: int = 8) -> Path:
    """The sector plot over the pings (every k-th for runs longer than ``MAX_FRAMES``), written as a GIF by Pillow."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    frames = list(range(0, len(pings), max(1, math.ceil(len(pings) / MAX_FRAMES))))
    fig, ax = plt.subplots(figsize=(6, 4.8))

    def frame(i: int):
        ax.clear()
        _draw(ax, sonar, pings, reports, clouds, i, truth_xy)
        return ()

    animation = FuncAnimation(fig, frame, frames=frames, blit=False)
    animation.save(path, writer=PillowWriter(fps=fps), dpi=70)
    plt.close(fig)
    return path
