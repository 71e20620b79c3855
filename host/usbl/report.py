"""Outputs of an INS+USBL run: ``track.csv``, ``summary.json`` and the plots (track, error over time, the
sound-speed profile with a ray), written into the run folder (``lost.host.runfolder``) through the shared summary
writer and plot guard (``lost.host.plotting``: a plot that fails is a warning, not a lost run).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ..consistency import BAND_PROBABILITY, nees, nees_figures
from ..plotting import draw_plots, pyplot
from ..runfolder import write_summary
from .pipeline import UsblRun
from .rays import trace_to_depth

__all__ = ["summarize", "track_table", "write_outputs", "run_plots", "NEES_BAND_PROBABILITY"]

NEES_BAND_PROBABILITY = BAND_PROBABILITY


def _stats(errors: np.ndarray) -> dict[str, float | int | None]:
    errors = errors[np.isfinite(errors)]
    if errors.size == 0:
        return {"rms_m": None, "p95_m": None, "max_m": None, "n": 0}
    return {"rms_m": float(np.sqrt(np.mean(errors**2))), "p95_m": float(np.percentile(errors, 95)), "max_m": float(errors.max()), "n": int(errors.size)}


def _status(run: UsblRun) -> np.ndarray:
    status = np.full(run.time_s.size, "dropout", dtype=object)
    for i, fix in enumerate(run.fixes):
        if fix is not None:
            status[i] = "fix"
    for i in run.fix_failures:
        status[i] = "failed"
    s = run.start_index
    fused = run.fused
    status[s:][fused.had_fix & fused.accepted] = "accepted"
    status[s:][fused.had_fix & ~fused.accepted] = "rejected"
    status[:s] = np.where(status[:s] == "fix", "before_alignment", status[:s])
    status[s - 1] = "alignment"
    return status


def track_table(run: UsblRun) -> pd.DataFrame:
    """One row per ping from the alignment on: the fused position (local, geographic, UTM) with its covariance,
    the ping's status and NIS, the raw USBL fix, and the truth and errors when known."""
    s, fused = run.start_index, run.fused
    north, east, down = fused.position.T
    lat, lon = run.frame.to_geographic(north, east)
    easting, northing = run.frame.to_utm(north, east)
    usbl = run.usbl_position[s:]
    table = pd.DataFrame({
        "time_s": fused.time_s, "lat_deg": lat, "lon_deg": lon, "utm_easting_m": easting, "utm_northing_m": northing,
        "north_m": north, "east_m": east, "depth_m": down,
        "var_north_m2": fused.covariance[:, 0, 0], "var_east_m2": fused.covariance[:, 1, 1], "cov_north_east_m2": fused.covariance[:, 0, 1],
        "var_depth_m2": fused.covariance[:, 2, 2], "status": _status(run)[s:], "nis": fused.nis,
        "usbl_north_m": usbl[:, 0], "usbl_east_m": usbl[:, 1],
    })
    if run.truth is not None:
        truth = run.truth[s:]
        table["true_north_m"], table["true_east_m"], table["true_depth_m"] = truth.T
        table["error_m"] = np.hypot(north - truth[:, 0], east - truth[:, 1])
        table["usbl_error_m"] = np.hypot(usbl[:, 0] - truth[:, 0], usbl[:, 1] - truth[:, 1])
        table["nees"] = nees(fused.position - truth, fused.covariance)
    return table


def summarize(run: UsblRun, *, name: str, run_time_s: float) -> dict[str, Any]:
    """The run's summary: methods with their error statistics when the truth is known, the gating counts, NEES."""
    s, fused = run.start_index, run.fused
    status = _status(run)
    counts = {key: int(np.sum(status == key)) for key in ("accepted", "rejected", "failed", "dropout", "before_alignment", "alignment")}
    summary: dict[str, Any] = {
        "name": name, "pings": int(run.time_s.size), "duration_s": float(run.time_s[-1] - run.time_s[0]), "run_time_s": run_time_s,
        "fused_epochs": int(fused.time_s.size), "epochs_before_start": s,
        "epochs_without_fused_position": int(np.sum(~np.all(np.isfinite(fused.position), axis=1))),
        "truth_known": run.truth is not None, "gate_chi2": fused.gate, "gating": counts,
        "frame": {"origin_lat_deg": run.frame.latitude0_deg, "origin_lon_deg": run.frame.longitude0_deg, "utm_crs": run.frame.utm_crs.to_string()},
    }
    if run.fix_failures:
        summary["gating"]["failed_examples"] = [{"row": row + 1, "reason": reason} for row, reason in sorted(run.fix_failures.items())[:5]]
    methods: dict[str, Any] = {}
    if run.truth is not None:
        truth = run.truth[s:]
        usbl = run.usbl_position
        horizontal = lambda p, t: np.hypot(p[:, 0] - t[:, 0], p[:, 1] - t[:, 1])  # noqa: E731
        methods["fused"] = _stats(horizontal(fused.position, truth))
        methods["usbl"] = _stats(horizontal(usbl, run.truth))
        methods["ins"] = _stats(horizontal(run.ins_position, truth))
        methods["dead_reckoning"] = _stats(horizontal(run.dead_reckoning, truth))
        summary["nees"] = nees_figures(nees(fused.position - truth, fused.covariance), 3, NEES_BAND_PROBABILITY)
        if run.injected is not None:
            good = np.array([f is not None for f in run.fixes]) & ~run.injected
            methods["usbl_good_fixes"] = _stats(np.where(good, horizontal(usbl, run.truth), np.nan))
            summary["gating"].update(_injected_counts(run, status))
    else:
        for method in ("fused", "usbl", "ins", "dead_reckoning"):
            methods[method] = {"rms_m": None, "p95_m": None, "max_m": None, "n": 0}
    summary["methods"] = methods
    if run.truth is not None and run.injected is not None:
        summary["goals"] = _goals(summary)
    return summary


def _goals(summary: dict[str, Any]) -> dict[str, bool]:
    """Issue #14's goals on a simulated run, each met or not."""
    methods, gating = summary["methods"], summary["gating"]
    caught, good_rejected = gating["injected_bad_caught_fraction"], gating["good_rejected_fraction"]
    return {
        "fused_position_at_every_epoch": summary["epochs_without_fused_position"] == 0,
        "fused_rms_at_most_half_raw_usbl": methods["fused"]["rms_m"] <= 0.5 * methods["usbl"]["rms_m"],
        "bad_fixes_caught_at_least_95_percent": caught is None or caught >= 0.95,
        "good_fixes_rejected_at_most_1_percent": good_rejected is None or good_rejected <= 0.01,
        "nees_inside_band_at_least_90_percent": summary["nees"]["fraction_inside"] >= 0.90,
    }


def _injected_counts(run: UsblRun, status: np.ndarray) -> dict[str, Any]:
    bad, replied = run.injected, np.isin(status, ("accepted", "rejected", "failed"))
    bad_rejected = int(np.sum(bad & (status == "rejected")))
    bad_failed = int(np.sum(bad & (status == "failed")))
    good = replied & ~bad
    good_rejected = int(np.sum(good & np.isin(status, ("rejected", "failed"))))
    n_bad = int(np.sum(bad & replied))
    return {"injected_bad": n_bad, "injected_bad_rejected_by_gate": bad_rejected, "injected_bad_refused_by_fix": bad_failed,
            "injected_bad_caught_fraction": (bad_rejected + bad_failed) / n_bad if n_bad else None,
            "good": int(np.sum(good)), "good_rejected": good_rejected, "good_rejected_fraction": good_rejected / int(np.sum(good)) if np.any(good) else None}


def write_outputs(out: Path, run: UsblRun, summary: dict[str, Any], warnings: list[str]) -> None:
    """``track.csv``, the plots (a plot that fails is a warning in ``warnings``), then ``summary.json`` with the warnings."""
    track_table(run).to_csv(out / "track.csv", index=False, float_format="%.6f")
    draw_plots(out, run_plots(run), warnings)
    summary["warnings"] = list(warnings)
    write_summary(out / "summary.json", summary)


def run_plots(run: UsblRun) -> dict[str, Callable[[Path], None]]:
    """The plots of a run by file name (``lost.host.plotting.draw_plots``): the track, the error over time (with the
    truth) and the sound-speed profile with a ray."""
    table = track_table(run)
    plots = {"track.png": lambda path: _plot_track(path, run, table)}
    if run.truth is not None:
        plots["error.png"] = lambda path: _plot_error(path, run, table)
    plots["profile.png"] = lambda path: _plot_profile(path, run)
    return plots


def _plot_track(path: Path, run: UsblRun, table: pd.DataFrame) -> None:
    fig, ax = pyplot().subplots(figsize=(8, 7))
    if run.truth is not None:
        ax.plot(run.truth[:, 1], run.truth[:, 0], color="k", lw=1, label="truth")
    ax.plot(run.ship[:, 1], run.ship[:, 0], color="0.6", lw=1, ls="--", label="ship (GNSS)")
    for status, style in (("accepted", dict(color="tab:blue", s=6)), ("rejected", dict(color="tab:red", s=14, marker="x"))):
        rows = table[table.status == status]
        ax.scatter(rows.usbl_east_m, rows.usbl_north_m, label=f"USBL {status}", **style)
    ax.plot(table.east_m, table.north_m, color="tab:green", lw=1.5, label="INS+USBL")
    ax.set(xlabel="east (m)", ylabel="north (m)", title="towfish track", aspect="equal")
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110, bbox_inches="tight", format="png")


def _plot_error(path: Path, run: UsblRun, table: pd.DataFrame) -> None:
    fig, ax = pyplot().subplots(figsize=(10, 4))
    ax.semilogy(table.time_s, table.usbl_error_m, ".", ms=3, color="tab:red", label="raw USBL")
    reckoning_error = np.hypot(*(run.dead_reckoning - run.truth[run.start_index:])[:, :2].T)
    ax.semilogy(table.time_s, reckoning_error, color="tab:orange", lw=1, label="eqs. 6-7 dead reckoning")
    ax.semilogy(table.time_s, table.error_m, color="tab:green", lw=1.5, label="INS+USBL")
    ax.semilogy(table.time_s, 2 * np.sqrt(table.var_north_m2 + table.var_east_m2), color="tab:green", lw=0.8, ls=":", label="INS+USBL 2 sigma")
    ax.set(xlabel="time (s)", ylabel="horizontal error (m)", title="error over time")
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=110, bbox_inches="tight", format="png")


def _plot_profile(path: Path, run: UsblRun) -> None:
    fig, (left, right, bend) = pyplot().subplots(1, 3, figsize=(13, 5), sharey=True)
    profile = run.profile
    left.plot(profile.speed_m_s, profile.depth_m, color="tab:blue")
    left.set(xlabel="sound speed (m/s)", ylabel="depth (m)", title="sound-speed layers")
    left.invert_yaxis()
    fixes = [f for f in run.fixes if f is not None]
    if fixes:
        fix = sorted(fixes, key=lambda f: f.slant_range_m)[len(fixes) // 2]
        top = max(fix.depth_m - np.sqrt(max(fix.slant_range_m**2 - fix.horizontal_range_m**2, 0.0)), 0.0)
        angle = _launch_angle(profile, top, fix)
        depths = np.linspace(top, fix.depth_m, 60)[1:]
        offsets = [0.0] + [trace_to_depth(profile, angle, top, d).horizontal_m for d in depths]
        right.plot(offsets, np.concatenate(([top], depths)), color="tab:blue", label="ray (eq. 3)")
        right.plot([0.0, fix.horizontal_range_m], [top, fix.depth_m], color="0.5", ls="--", label="straight line")
        right.set(xlabel="horizontal offset (m)", title=f"a ray: slant range {fix.slant_range_m:.1f} m")
        right.legend(fontsize=8)
        chord = np.concatenate(([0.0], (depths - top) / (fix.depth_m - top) * fix.horizontal_range_m))
        bend.plot(np.array(offsets) - chord, np.concatenate(([top], depths)), color="tab:blue")
        bend.axvline(0.0, color="0.5", ls="--")
        bend.set(xlabel="ray minus straight line (m)", title="the ray's bending")
    fig.savefig(path, dpi=110, bbox_inches="tight", format="png")


def _launch_angle(profile, top: float, fix) -> float:
    from scipy.optimize import brentq

    return brentq(lambda a: trace_to_depth(profile, a, top, fix.depth_m).horizontal_m - fix.horizontal_range_m, 0.0, 1.4)
