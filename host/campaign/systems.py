"""The systems a campaign runs: the terrain navigation, the contact tracker and the INS+USBL positioning.

Each system names its scenarios (shipped names or TOML files), its estimators (the rows of one run) and the figures
of a row; :func:`system_rows` simulates one run of a scenario (already given its seed and values) and measures it
with the system's own public functions, as its command and its benchmark do.

- ``nav``: ``lost.host.scenario`` tows navigated by ``lost.host.nav`` (estimators ``lost``, ``pmf``, ``pf``): RMS, p95,
  max after convergence, NEES in band, false fixes, usable share, convergence time, time per update.
- ``track``: ``lost.host.track`` scenarios (estimators: ``ours``, and Stone Soup's ``gm_phd`` and ``jpda``): coverage
  (mean over targets), first lock (pings to the first hold, the slowest target), identity switches, false tracks
  (and per hour), GOSPA mean and 95th percentile over the pings with a target in the sector, time per ping.
- ``usbl``: ``lost.host.usbl`` scenarios (one estimator, ``fused``): the fused position's RMS, p95 and max, the raw
  USBL's RMS, NEES in band, good fixes rejected and injected bad fixes caught (shares).
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["SYSTEMS", "FIGURES", "PLOTTED", "system_of", "estimators_of", "load_system_scenario", "system_rows"]

#: The systems a campaign runs.
SYSTEMS = ("nav", "track", "usbl")

#: Each system's figures of a row (``summary.json`` gives their median and 90th percentile per case and estimator).
FIGURES = {
    "nav": ("rms_m", "p95_m", "max_m", "usable_rms_m", "nees_in_band", "false_fixes", "usable_fraction", "convergence_time_s", "ms_per_update"),
    "track": ("coverage", "first_lock", "identity_switches", "false_tracks", "false_per_hour", "gospa_mean", "gospa_p95", "ms_per_ping"),
    "usbl": ("rms_m", "p95_m", "max_m", "usbl_rms_m", "nees_in_band", "good_rejected", "bad_caught"),
}

#: The figures ``distributions.png`` draws of each system, with their titles.
PLOTTED = {
    "nav": (("rms_nodes", "RMS after convergence (map nodes)"), ("nees_in_band", "NEES in band (share)"), ("false_fixes", "false fixes per run")),
    "track": (("coverage", "coverage (share of in-sector pings held)"), ("gospa_mean", "GOSPA mean (m)"), ("false_per_hour", "false tracks per hour")),
    "usbl": (("rms_m", "fused RMS (m)"), ("nees_in_band", "NEES in band (share)"), ("good_rejected", "good fixes rejected (share)")),
}

_TRACKERS = ("ours", "gm_phd", "jpda")


def system_of(table) -> str:
    """The system of a campaign's table (its rows say; ``nav`` for a table from before the column)."""
    if "system" in table and table["system"].notna().any():
        return str(table["system"].dropna().iloc[0])
    return "nav"


def estimators_of(system: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The estimators a system knows, and those a campaign runs when its file names none."""
    if system == "nav":
        from ..nav import ESTIMATORS

        return tuple(ESTIMATORS), tuple(ESTIMATORS)
    if system == "track":
        return _TRACKERS, ("ours",)
    return ("fused",), ("fused",)


def load_system_scenario(system: str, path: Path) -> Any:
    """The scenario at ``path`` (a file) or named ``path.name`` (shipped) of ``system``."""
    name = str(path.name)
    if system == "nav":
        from ..scenario import builtin_scenario_path, load_scenario

        return load_scenario(path if name.endswith(".toml") or path.exists() else builtin_scenario_path(name))
    if system == "track":
        from ..track.simulate import builtin_scenario_path, load_scenario

        return load_scenario(path if name.endswith(".toml") or path.exists() else builtin_scenario_path(name))
    from ..usbl.scenario import load_usbl_scenario

    return load_usbl_scenario(path if name.endswith(".toml") or path.exists() else name)


def system_rows(system: str, scenario: Any, estimators: tuple[str, ...]) -> list[dict[str, Any]]:
    """One row per estimator of one run of ``scenario`` (its seed and values already set)."""
    return {"nav": _nav_rows, "track": _track_rows, "usbl": _usbl_rows}[system](scenario, estimators)


def _nav_rows(scenario: Any, estimators: tuple[str, ...]) -> list[dict[str, Any]]:
    from ..nav import NavParameters, navigate
    from ..report import summarize
    from ..scenario import simulate

    grid, records = simulate(scenario)
    start = time.perf_counter()
    result = navigate(records, grid, NavParameters(**scenario.navigation), estimators=estimators)
    summary = summarize(result, name=scenario.name, parameters={}, run_time_s=time.perf_counter() - start)
    rows = []
    for estimator in estimators:
        figures = summary["methods"].get(estimator, {})
        row = {name: figures.get(name) for name in FIGURES["nav"]}
        if estimator == "lost":
            row["convergence_time_s"] = summary["convergence"].get("time_s")
        rms, usable_rms = row["rms_m"], row["usable_rms_m"]
        rows.append({"estimator": estimator, "node_m": grid.node_m, "rms_nodes": None if rms is None else rms / grid.node_m,
                     "usable_rms_nodes": None if usable_rms is None else usable_rms / grid.node_m, **row,
                     "records": summary["records"], "run_time_s": summary["run_time_s"]})
    return rows


def _track_rows(scenario: Any, estimators: tuple[str, ...]) -> list[dict[str, Any]]:
    from ..config import build
    from ..track.baseline import run_gm_phd, run_jpda
    from ..track.evaluate import contact_metrics, score
    from ..track.run import run_tracker
    from ..track.simulate import simulate, tracker_model
    from ..track.tracker import TrackerParameters

    sim = simulate(scenario)
    model = scenario.sonar
    params = build(TrackerParameters, {**tracker_model(model), **scenario.tracker}, f"[tracker] of {scenario.name}")
    hours = len(sim.pings) * model.ping_interval_s / 3600.0
    rows = []
    for tracker in estimators:
        start = time.perf_counter()
        if tracker == "ours":
            history = run_tracker(sim.pings, sonar=model.sonar, parameters=params, seed=scenario.seed, cloud_points=0).estimates
        else:
            history = (run_gm_phd if tracker == "gm_phd" else run_jpda)(sim.pings, sonar=model.sonar, tracker=params)
        elapsed = time.perf_counter() - start
        s = score(history, sim.truth, siap=False)
        gospa = np.asarray(s.gospa_per_ping)[sim.truth.in_sector.any(axis=1)] if sim.truth.xy.shape[1] else np.asarray(s.gospa_per_ping)
        row = {"estimator": tracker, "false_tracks": s.false_tracks, "false_per_hour": s.false_tracks / hours if hours else None,
               "gospa_mean": float(gospa.mean()) if gospa.size else None, "gospa_p95": float(np.percentile(gospa, 95)) if gospa.size else None,
               "ms_per_ping": elapsed / max(len(sim.pings), 1) * 1e3, "pings": len(sim.pings), "run_time_s": elapsed}
        if sim.truth.xy.shape[1]:
            contact = contact_metrics(history, sim.truth)
            coverage = [c for c in contact["coverage"] if c is not None]
            row.update(coverage=float(np.mean(coverage)) if coverage else None,
                       first_lock=None if None in contact["first_lock"] else max(contact["first_lock"]),
                       identity_switches=int(sum(contact["identity_switches"])))
        rows.append(row)
    return rows


def _usbl_rows(scenario: Any, estimators: tuple[str, ...]) -> list[dict[str, Any]]:
    from ..usbl.ins import ImuSamples
    from ..usbl.pipeline import process
    from ..usbl.report import summarize
    from ..usbl.simulate import simulate_tow

    sim = simulate_tow(scenario)
    imu = ImuSamples(sim.imu.time_s.to_numpy(), sim.imu[["fx_m_s2", "fy_m_s2", "fz_m_s2"]].to_numpy(),
                     sim.imu[["wx_rad_s", "wy_rad_s", "wz_rad_s"]].to_numpy())
    start = time.perf_counter()
    run = process(sim.log, imu, sim.cast, scenario.processing_config())
    summary = summarize(run, name=scenario.name, run_time_s=time.perf_counter() - start)
    fused, gating = summary["methods"]["fused"], summary["gating"]
    return [{"estimator": "fused", "rms_m": fused["rms_m"], "p95_m": fused["p95_m"], "max_m": fused["max_m"],
             "usbl_rms_m": summary["methods"]["usbl"]["rms_m"], "nees_in_band": summary["nees"]["fraction_inside"],
             "good_rejected": gating.get("good_rejected_fraction"), "bad_caught": gating.get("injected_bad_caught_fraction"),
             "pings": summary["pings"], "run_time_s": summary["run_time_s"]}]
