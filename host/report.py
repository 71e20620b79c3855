"""What a run leaves behind: the track CSV, ``summary.json`` and PNG plots.

"After convergence", precisely: an estimator has converged at the first record from which its
horizontal error stays within ``radius_m`` (default 20 m, two map nodes) for ``hold_s`` seconds
(default 60 s) without a break; its after-convergence statistics are taken over the records from that
moment to the end of the run, excursions included. The baselines are measured from LOST's moment (the
top-level ``convergence``). A run that never converges reports ``converged: false`` and no
after-convergence figures.

The Bayesian filters' trust figures (``methods.pmf``, ``methods.pf``):

- ``nees_in_band``: the share of terrain updates after convergence whose NEES (the squared error
  weighted by the inverse covariance, chi-square with 2 degrees of freedom for a consistent filter)
  lies in its two-sided 95 % band [0.051, 7.38];
- ``false_fixes``: records flagged usable whose error lies beyond 3 sigma (NEES above 11.83);
- ``usable_fraction``: the share of records flagged usable;
- ``usable_rms_m``, ``usable_records``: the RMS error after convergence over the records flagged usable alone (what a
  user who trusts the flag gets; where the terrain holds no information the filter says so, and the plain RMS
  counts those stretches too);
- ``ms_per_update``: the median wall time of the estimator's work at a record, milliseconds;
- ``depth_bias_m``: the single-depth form's last depth-bias estimate (measured minus map), metres;
  None for the patch form, which needs none;
- ``velocity_bias_mps``, ``velocity_bias_sigma_mps``: the last velocity-bias estimate (the measured velocity
  less the true, [east, north], m/s) and its 1-sigma: what the tow taught of its DVL or INS.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .consistency import nees, nees_band, three_sigma
from .grid import Grid
from .nav.pipeline import FilterTrack, NavResult
from .plotting import map_figure_size, pyplot
from .runfolder import write_summary

__all__ = ["ConvergenceRule", "error_stats", "convergence_index", "summarize", "write_track_csv", "write_summary", "run_plots", "METHODS"]

#: summary.json's method names and the NavResult fields they read.
METHODS = {"lost": "estimate", "layback": "layback", "dead_reckoning": "dead_reckoning"}

#: NEES of a consistent 2-D estimate: its two-sided 95 % band, and 3 sigma (99.73 %).
NEES_BAND = nees_band(2)
NEES_3_SIGMA = three_sigma(2)
#: Stages at which a filter made a terrain update.
UPDATE_STAGES = ("acquisition", "tracking")


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


def track_nees(track: FilterTrack, truth: np.ndarray) -> np.ndarray:
    """The NEES of every record of a filter's track (NaN without an estimate or a covariance)."""
    return nees(track.position - truth, track.covariance)

def _last_finite(values: np.ndarray, digits: int = 3) -> float | list[float] | None:
    """The last finite value of an (N,) series, or the last row of an (N, 2) one with both finite; None without one."""
    rows = values.reshape(len(values), -1)
    finite = rows[np.isfinite(rows).all(axis=1)]
    if not len(finite):
        return None
    last = [round(float(v), digits) for v in finite[-1]]
    return last if values.ndim > 1 else last[0]


def filter_figures(track: FilterTrack, truth: np.ndarray | None, start: int | None) -> dict[str, Any]:
    """The trust figures of one Bayesian filter (see the module docstring); None where the truth is needed but unknown."""
    updates = np.isin(track.stage, UPDATE_STAGES)
    timed = np.isfinite(track.ms) & (track.stage != "initialization")
    figures: dict[str, Any] = {
        "usable_fraction": round(float(track.usable.mean()), 4) if len(track.usable) else None,
        "ms_per_update": round(float(np.median(track.ms[timed])), 3) if timed.any() else None,
        "terrain_updates": int(updates.sum()),
        "counts": dict(track.counts),
        "nees_in_band": None,
        "false_fixes": None,
        "depth_bias_m": _last_finite(track.depth_bias_m),
        "velocity_bias_mps": _last_finite(track.velocity_bias_mps, 4),
        "velocity_bias_sigma_mps": _last_finite(track.velocity_bias_sigma_mps, 4),
    }
    if truth is None:
        return figures
    value = track_nees(track, truth)
    figures["false_fixes"] = int(np.count_nonzero(track.usable & (value > NEES_3_SIGMA)))
    if start is not None:
        after = updates & (np.arange(len(value)) >= start) & np.isfinite(value)
        if after.any():
            inside = (value[after] >= NEES_BAND[0]) & (value[after] <= NEES_BAND[1])
            figures["nees_in_band"] = round(float(inside.mean()), 4)
    return figures


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
    filters = {name: track for name, track in result.tracks.items() if name != "lost"}
    if result.truth is None:
        for name, track in filters.items():
            summary["methods"][name] = filter_figures(track, None, None)
        return summary
    errors = {method: horizontal_error(getattr(result, field), result.truth) for method, field in METHODS.items()}
    # The top-level convergence is LOST's, or the first filter's when LOST did not run.
    primary = "lost" if "lost" in result.tracks or not result.tracks else next(iter(result.tracks))
    reference = errors["lost"] if primary == "lost" else horizontal_error(result.tracks[primary].position, result.truth)
    start = convergence_index(result.t_s, reference, rule)
    first = np.flatnonzero(np.isfinite(reference))
    summary["convergence"].update(
        estimator=primary,
        converged=start is not None,
        time_s=None if start is None else float(result.t_s[start] - result.t_s[0]),
        initial_error_m=None if not first.size else round(float(reference[first[0]]), 3),
    )
    for method, error in errors.items():
        if method == "lost" and not _ran_lost(result):
            continue
        summary["methods"][method] = _accuracy(error, start)
    for name, track in filters.items():
        error = horizontal_error(track.position, result.truth)
        own = convergence_index(result.t_s, error, rule)
        summary["methods"][name] = {
            **_accuracy(error, own),
            "converged": own is not None,
            "convergence_time_s": None if own is None else float(result.t_s[own] - result.t_s[0]),
            **filter_figures(track, result.truth, own),
            **_usable_accuracy(error, track.usable, own),
        }
    return summary


def _usable_accuracy(error: np.ndarray, usable: np.ndarray, start: int | None) -> dict[str, Any]:
    """The RMS error after convergence over the records flagged usable (None without convergence or such a record)."""
    if start is None:
        return {"usable_rms_m": None, "usable_records": 0}
    trusted = error_stats(np.where(np.asarray(usable, bool), error, np.nan)[start:])
    return {"usable_rms_m": trusted["rms_m"], "usable_records": trusted["records"]}


def _accuracy(error: np.ndarray, start: int | None) -> dict[str, Any]:
    after = error_stats(error[start:]) if start is not None else {"rms_m": None, "p95_m": None, "max_m": None, "records": 0}
    return {**after, "whole_run": error_stats(error)}


def _fmt(value: float, digits: int = 3) -> str:
    return "" if not math.isfinite(value) else f"{value:.{digits}f}"


def write_track_csv(path: Path, result: NavResult) -> None:
    """One row per record: time, estimate, truth, every stage's output, the baselines and the flags.

    ``stage`` says what produced the estimate: ``patch`` or ``point`` (an MLE at that record, which the
    tracker used unless the ship's fix was missing, counted as ``cat_no_ship_fix``),
    ``dead_reckoning`` (no MLE), ``off_map`` (dead reckoning because the prediction left the map),
    ``initialization`` (the lay-back start) or ``uninitialized``. Empty cells are missing values.

    Each Bayesian filter that ran adds ``<name>_x_m``, ``<name>_y_m``, its covariance
    (``<name>_sxx``, ``<name>_syy``, ``<name>_sxy``, m**2), ``<name>_usable`` (0/1), ``<name>_nis``,
    ``<name>_stage``, ``<name>_rejected``, ``<name>_error_m``, ``<name>_depth_bias_m`` (the
    single-depth form's depth-bias estimate, measured minus map; empty for the patch form) and the
    velocity-bias estimate with its 1-sigma, m/s (``<name>_velocity_bias_e_mps``, ``_n_mps``,
    ``<name>_velocity_bias_sigma_e_mps``, ``_sigma_n_mps``), ``<name>_held`` (0/1: the estimate held within dead
    reckoning's 3 sigma, :mod:`lost.host.nav.guard`) and ``<name>_reinitialized`` (the cause of a re-initialization
    at that record, empty when none).
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
    filters = {name: track for name, track in result.tracks.items() if name != "lost"}
    for name in filters:
        header += [f"{name}_{column}" for column in ("x_m", "y_m", "sxx", "syy", "sxy", "usable", "nis", "stage", "rejected", "error_m",
                                                       "depth_bias_m", "velocity_bias_e_mps", "velocity_bias_n_mps",
                                                       "velocity_bias_sigma_e_mps", "velocity_bias_sigma_n_mps", "held", "reinitialized")]
    filter_errors = {name: horizontal_error(track.position, truth) for name, track in filters.items()}
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
                 _fmt(errors["layback"][n]), *map(_fmt, result.dead_reckoning[n]), _fmt(errors["dead_reckoning"][n]),
                 *(cell for name, track in filters.items() for cell in _filter_cells(track, n, filter_errors[name][n]))]
            )


def _filter_cells(track: FilterTrack, n: int, error: float) -> list[str]:
    c = track.covariance[n]
    return [*map(_fmt, track.position[n]), _fmt(c[0, 0]), _fmt(c[1, 1]), _fmt(c[0, 1]), str(int(track.usable[n])), _fmt(track.nis[n]),
            str(track.stage[n]), str(track.rejected[n]), _fmt(error), _fmt(track.depth_bias_m[n]),
            *(_fmt(v, 4) for v in (*track.velocity_bias_mps[n], *track.velocity_bias_sigma_mps[n])),
            "" if track.held is None else str(int(track.held[n])), "" if track.reinitialized is None else str(track.reinitialized[n])]


#: Colour and line style of each method in the plots.
STYLES = {"layback": ("tab:orange", "--"), "dead_reckoning": ("tab:gray", ":"), "lost": ("tab:red", "-"), "pmf": ("tab:blue", "-"),
          "pf": ("tab:purple", "-")}


def _ran_lost(result: NavResult) -> bool:
    """Whether the patent pipeline ran (a result built without estimator tracks is the patent's alone)."""
    return not result.tracks or "lost" in result.tracks


def _tracks(result: NavResult) -> dict[str, np.ndarray]:
    """Every method's positions by name, those that ran."""
    tracks = {method: getattr(result, field) for method, field in METHODS.items() if method != "lost" or _ran_lost(result)}
    tracks.update({name: track.position for name, track in result.tracks.items() if name != "lost"})
    return tracks


def run_plots(result: NavResult, grid: Grid, summary: dict[str, Any]) -> dict[str, Callable[[Path], None]]:
    """The plots of a run by file name, for :func:`lost.host.plotting.draw_plots`: ``map.png`` (the bathymetry with the
    tracks and the filters' 2-sigma ellipses) and, when the truth is known, ``error.png`` (each method's error, each
    filter's 2-sigma radius as a band)."""
    plots = {"map.png": lambda path: _plot_map(path, result, grid, summary)}
    if result.truth is not None:
        plots["error.png"] = lambda path: _plot_errors(path, result, summary)
    return plots


def _plot_map(path: Path, result: NavResult, grid: Grid, summary: dict[str, Any]) -> None:
    plt = pyplot()
    xlim, ylim = _map_frame(result, grid)
    fig, ax = plt.subplots(figsize=map_figure_size(xlim[1] - xlim[0], ylim[1] - ylim[0]), layout="constrained")
    _draw_map(fig, ax, result, grid, summary, xlim, ylim)
    fig.savefig(path, dpi=110)


def _plot_errors(path: Path, result: NavResult, summary: dict[str, Any]) -> None:
    fig, ax = pyplot().subplots(figsize=(10, 4), layout="constrained")
    _draw_errors(ax, result, summary)
    fig.savefig(path, dpi=110)


def _map_extent(grid: Grid) -> tuple[float, float, float, float]:
    rows, cols = grid.shape
    return (grid.x0_m - grid.node_m / 2, grid.x0_m + (cols - 0.5) * grid.node_m,
            grid.y0_m - grid.node_m / 2, grid.y0_m + (rows - 0.5) * grid.node_m)


def _map_frame(result: NavResult, grid: Grid) -> tuple[tuple[float, float], tuple[float, float]]:
    """The tracks with a margin of a search area, within the map: the part of the map the plot shows."""
    extent = _map_extent(grid)
    points = np.vstack(list(_tracks(result).values()) + ([result.truth] if result.truth is not None else []))
    if not np.isfinite(points).any():
        return (extent[0], extent[1]), (extent[2], extent[3])
    low, high = np.nanmin(points, axis=0) - 500.0, np.nanmax(points, axis=0) + 500.0
    return (max(low[0], extent[0]), min(high[0], extent[1])), (max(low[1], extent[2]), min(high[1], extent[3]))


def _two_sigma_radius(covariance: np.ndarray) -> np.ndarray:
    """Twice the larger 1-sigma axis of each covariance, metres."""
    return 2.0 * np.sqrt(np.maximum(np.linalg.eigvalsh(np.nan_to_num(covariance))[:, -1], 0.0))


def _draw_map(fig, ax, result: NavResult, grid: Grid, summary: dict[str, Any], xlim: tuple[float, float], ylim: tuple[float, float]) -> None:
    from matplotlib.patches import Ellipse

    extent = _map_extent(grid)
    image = ax.imshow(grid.depth_m, origin="lower", extent=extent, cmap="viridis_r")
    fig.colorbar(image, ax=ax, label="depth (m)")
    if result.truth is not None:
        ax.plot(result.truth[:, 0], result.truth[:, 1], color="white", lw=2.5, label="truth")
    tracks = _tracks(result)
    for method, track in tracks.items():
        color, style = STYLES[method]
        ax.plot(track[:, 0], track[:, 1], color=color, ls=style, lw=1.2, label=method)
    for name, track in result.tracks.items():
        if name == "lost":
            continue
        # A 2-sigma ellipse at about twenty records along the run.
        for n in np.linspace(0, len(result.t_s) - 1, 20).astype(int):
            if not np.isfinite(track.covariance[n]).all() or not np.isfinite(track.position[n]).all():
                continue
            values, vectors = np.linalg.eigh(track.covariance[n])
            angle = float(np.degrees(np.arctan2(vectors[1, 1], vectors[0, 1])))
            width, height = 4.0 * np.sqrt(np.maximum(values[::-1], 0.0))
            ax.add_patch(Ellipse(track.position[n], width, height, angle=angle, fill=False, color=STYLES[name][0], lw=0.8))
    ax.set(xlim=xlim, ylim=ylim)
    ax.set(xlabel="easting (m)", ylabel="northing (m)", title=f"{summary['name']}: tracks over the map (2-sigma ellipses)", aspect="equal")
    ax.legend(loc="upper right", fontsize="small")


def _draw_errors(ax, result: NavResult, summary: dict[str, Any]) -> None:
    for method, track in _tracks(result).items():
        color, style = STYLES[method]
        ax.plot(result.t_s, horizontal_error(track, result.truth), color=color, ls=style, lw=1.0, label=method)
    for name, track in result.tracks.items():
        if name != "lost":
            ax.fill_between(result.t_s, 0.0, _two_sigma_radius(track.covariance), color=STYLES[name][0], alpha=0.15, lw=0,
                            label=f"{name} 2 sigma")
    converged = summary["convergence"].get("time_s")
    if converged is not None:
        ax.axvline(result.t_s[0] + converged, color="black", lw=0.8, label=f"{summary['convergence']['estimator']} converged")
    ax.set(xlabel="time (s)", ylabel="horizontal error (m)", yscale="log", title=f"{summary['name']}: horizontal error")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small", ncol=2)
