"""What a run leaves behind: the track CSV, ``summary.json`` and PNG plots.

"After convergence", precisely: LOST has converged at the first record from which its horizontal
error stays within ``radius_m`` (default 20 m, two map nodes) for ``hold_s`` seconds (default 60 s)
without a break; the after-convergence statistics of every method are taken over the records from
that moment to the end of the run, excursions included. A run that never converges reports
``converged: false`` and no after-convergence figures.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .grid import Grid
from .nav.pipeline import NavResult

__all__ = ["ConvergenceRule", "error_stats", "convergence_index", "summarize", "write_track_csv", "write_summary", "plot_run", "METHODS"]

#: summary.json's method names and the NavResult fields they read.
METHODS = {"lost": "estimate", "layback": "layback", "dead_reckoning": "dead_reckoning"}


@dataclass(frozen=True, kw_only=True)
class ConvergenceRule:
    """When LOST counts as converged (see the module docstring)."""

    radius_m: float = 20.0
    hold_s: float = 60.0

    def __post_init__(self) -> None:
        if not (self.radius_m > 0 and self.hold_s >= 0):
            raise ValueError(f"The convergence radius must be positive and the hold time not negative, got {self.radius_m!r} m and {self.hold_s!r} s.")

    def describe(self) -> str:
        return (
            f"converged at the first record from which LOST's horizontal error stays within {self.radius_m:g} m "
            f"for {self.hold_s:g} s; after-convergence figures cover every record from then to the end"
        )


def horizontal_error(positions: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Distance of each estimate from the truth, metres (NaN where either is missing)."""
    return np.hypot(positions[:, 0] - truth[:, 0], positions[:, 1] - truth[:, 1])


def error_stats(errors: np.ndarray) -> dict[str, float | int | None]:
    """RMS, 95th percentile and maximum of the finite errors, with how many there were."""
    finite = errors[np.isfinite(errors)]
    if finite.size == 0:
        return {"rms_m": None, "p95_m": None, "max_m": None, "records": 0}
    return {
        "rms_m": round(float(np.sqrt(np.mean(finite**2))), 3),
        "p95_m": round(float(np.percentile(finite, 95)), 3),
        "max_m": round(float(finite.max()), 3),
        "records": int(finite.size),
    }


def convergence_index(t_s: np.ndarray, errors: np.ndarray, rule: ConvergenceRule) -> int | None:
    """Index of the first record of the first unbroken stretch within ``rule.radius_m`` lasting ``rule.hold_s``."""
    inside = np.isfinite(errors) & (errors <= rule.radius_m)
    start = None
    for n in range(len(t_s)):
        if not inside[n]:
            start = None
            continue
        if start is None:
            start = n
        if t_s[n] - t_s[start] >= rule.hold_s:
            return start
    return None


def summarize(result: NavResult, *, name: str, parameters: dict[str, Any], rule: ConvergenceRule | None = None,
              run_time_s: float | None = None) -> dict[str, Any]:
    """The content of summary.json for one run."""
    rule = rule or ConvergenceRule()
    summary: dict[str, Any] = {
        "name": name,
        "records": int(len(result.t_s)),
        "duration_s": float(result.t_s[-1] - result.t_s[0]) if len(result.t_s) else 0.0,
        "parameters": parameters,
        "counts": result.counts,
        "off_map_records": int(result.off_map.sum()),
        "dead_reckoning_records": int(np.count_nonzero(result.mle_source == "")),
        "run_time_s": None if run_time_s is None else round(run_time_s, 3),
        "truth_known": result.truth is not None,
        "convergence": {"definition": rule.describe(), "radius_m": rule.radius_m, "hold_s": rule.hold_s},
        "methods": {},
    }
    if result.truth is None:
        return summary
    errors = {method: horizontal_error(getattr(result, field), result.truth) for method, field in METHODS.items()}
    start = convergence_index(result.t_s, errors["lost"], rule)
    first = np.flatnonzero(np.isfinite(errors["lost"]))
    summary["convergence"].update(
        converged=start is not None,
        time_s=None if start is None else float(result.t_s[start] - result.t_s[0]),
        initial_error_m=None if not first.size else round(float(errors["lost"][first[0]]), 3),
    )
    for method, error in errors.items():
        after = error_stats(error[start:]) if start is not None else {"rms_m": None, "p95_m": None, "max_m": None, "records": 0}
        summary["methods"][method] = {**after, "whole_run": error_stats(error)}
    return summary


def _fmt(value: float) -> str:
    return "" if not math.isfinite(value) else f"{value:.3f}"


def write_track_csv(path: Path, result: NavResult) -> None:
    """One row per record: time, estimate, truth, every stage's output, the baselines and the flags.

    ``stage`` says what produced the estimate: ``patch`` or ``point`` (an MLE at that record, which the
    tracker used unless the ship's fix was missing, counted as ``cat_no_ship_fix``),
    ``dead_reckoning`` (no MLE), ``off_map`` (dead reckoning because the prediction left the map),
    ``initialization`` (the lay-back start) or ``uninitialized``. Empty cells are missing values.
    """
    started = np.flatnonzero(np.isfinite(result.estimate[:, 0]))
    first = int(started[0]) if started.size else -1
    truth = result.truth if result.truth is not None else np.full_like(result.estimate, np.nan)
    errors = {m: horizontal_error(getattr(result, f), truth) for m, f in METHODS.items()}
    header = [
        "t_s", "est_x_m", "est_y_m", "truth_x_m", "truth_y_m", "error_m", "stage", "off_map",
        "pred_x_m", "pred_y_m", "mle_x_m", "mle_y_m", "distinctness", "cat_x_m", "cat_y_m", "cross_velocity_mps",
        "slant_corrected", "layback_x_m", "layback_y_m", "layback_error_m", "dr_x_m", "dr_y_m", "dr_error_m",
    ]
    with open(path, "w", newline="") as stream:
        writer = csv.writer(stream)
        writer.writerow(header)
        for n in range(len(result.t_s)):
            if not np.isfinite(result.estimate[n, 0]):
                stage = "uninitialized"
            elif n == first:
                stage = "initialization"
            elif result.off_map[n]:
                stage = "off_map"
            else:
                stage = result.mle_source[n] or "dead_reckoning"
            writer.writerow(
                [f"{result.t_s[n]:.3f}", *map(_fmt, result.estimate[n]), *map(_fmt, truth[n]), _fmt(errors["lost"][n]), stage,
                 int(result.off_map[n]), *map(_fmt, result.predicted[n]), *map(_fmt, result.mle[n]), _fmt(result.distinctness[n]),
                 *map(_fmt, result.cat[n]),
                 _fmt(result.cross_velocity_mps[n]), int(result.slant_corrected[n]), *map(_fmt, result.layback[n]),
                 _fmt(errors["layback"][n]), *map(_fmt, result.dead_reckoning[n]), _fmt(errors["dead_reckoning"][n])]
            )


def write_summary(path: Path, summary: dict[str, Any]) -> None:
    path.write_text(json.dumps(summary, indent=2, allow_nan=False) + "\n")


def plot_run(out_dir: Path, result: NavResult, grid: Grid, summary: dict[str, Any]) -> list[Path]:
    """``map.png`` (the bathymetry with the tracks) and, when the truth is known, ``error.png``."""
    import matplotlib

    matplotlib.use("Agg")  # files only, no display
    import matplotlib.pyplot as plt

    paths = []
    rows, cols = grid.shape
    extent = (grid.x0_m - grid.node_m / 2, grid.x0_m + (cols - 0.5) * grid.node_m,
              grid.y0_m - grid.node_m / 2, grid.y0_m + (rows - 0.5) * grid.node_m)
    fig, ax = plt.subplots(figsize=(10, 6), layout="constrained")
    image = ax.imshow(grid.depth_m, origin="lower", extent=extent, cmap="viridis_r")
    fig.colorbar(image, ax=ax, label="depth (m)")
    styles = {"layback": ("tab:orange", "--"), "dead_reckoning": ("tab:gray", ":"), "lost": ("tab:red", "-")}
    if result.truth is not None:
        ax.plot(result.truth[:, 0], result.truth[:, 1], color="white", lw=2.5, label="truth")
    for method, field in METHODS.items():
        color, style = styles[method]
        track = getattr(result, field)
        ax.plot(track[:, 0], track[:, 1], color=color, ls=style, lw=1.2, label=method)
    # Frame the tracks, not the whole map, with a margin of a search area.
    tracks = np.vstack([getattr(result, field) for field in METHODS.values()] + ([result.truth] if result.truth is not None else []))
    low, high = np.nanmin(tracks, axis=0) - 500.0, np.nanmax(tracks, axis=0) + 500.0
    ax.set(xlim=(max(low[0], extent[0]), min(high[0], extent[1])), ylim=(max(low[1], extent[2]), min(high[1], extent[3])))
    ax.set(xlabel="easting (m)", ylabel="northing (m)", title=f"{summary['name']}: tracks over the map", aspect="equal")
    ax.legend(loc="upper right", fontsize="small")
    paths.append(out_dir / "map.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    if result.truth is None:
        return paths
    fig, ax = plt.subplots(figsize=(10, 4), layout="constrained")
    for method, field in METHODS.items():
        color, style = styles[method]
        ax.plot(result.t_s, horizontal_error(getattr(result, field), result.truth), color=color, ls=style, label=method)
    converged = summary["convergence"].get("time_s")
    if converged is not None:
        ax.axvline(result.t_s[0] + converged, color="black", lw=0.8, label="converged")
    ax.set(xlabel="time (s)", ylabel="horizontal error (m)", yscale="log", title=f"{summary['name']}: horizontal error")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    paths.append(out_dir / "error.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    return paths
