"""``lost track``: contact tracking on recorded detections or a simulated scenario.

::

    lost track DETECTIONS.csv [--truth T.csv] [--out DIR]   recorded detections (layout: lost.host.track.detections)
    lost track SCENARIO.toml|NAME [--out DIR]        a simulated run (built-in: one_diver, two_divers, clutter_hour)
        [--baseline] [--particles N] [--seed S] [--pd P] [--clutter RATE] [--set NAME=VALUE ...]
        [--max-range M] [--half-fov DEG] [--crs EPSG:...] [--no-animation] [--write-detections]

Writes ``tracks.csv``, ``sector.png`` (the paper's Figure 5 at the last ping), ``tracks.gif`` (the pings
animated) and, last, ``summary.json`` into ``--out`` (default ``runs/track/NAME``). With a scenario, or a
CSV with ``--truth``, the truth is known, so the summary holds the lock, false tracks and Stone Soup's GOSPA/OSPA/SIAP; ``--baseline`` runs Stone
Soup's GM-PHD and JPDA (with an M-of-N initiator) on the same pings and adds their figures (``baselines``).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from ..plotting import draw_plots
from ..runfolder import run_folder, write_summary
from ..track.detections import read_detections, write_detections
from ..track.evaluate import score
from ..track.geometry import Sonar
from ..track.output import track_table, write_tracks_csv
from ..track.run import run_tracker
from ..track.simulate import builtin_scenario_path, load_scenario, simulate, tracker_model
from ..track.tracker import TrackerParameters
from .common import merge_settings, output_options, progress_bar, settings_option, warnings_collected

__all__ = ["register", "run_track"]


def _parameters(base: dict, overrides: dict, where: str) -> TrackerParameters:
    from ..config import build

    def check(table, layer):
        return build(TrackerParameters, {**base, **table}, layer)

    merged = merge_settings([(where, overrides)], TrackerParameters.__dataclass_fields__, "tracker parameter", check)
    return build(TrackerParameters, {**base, **merged}, "tracker")


def _load(source: str, args: argparse.Namespace):
    """Pings, sonar, tracker parameters, truth (or None), a name and notes, from a CSV or a scenario."""
    path = Path(source)
    overrides = {k: v for k, v in (("particles", args.particles), ("pd", args.pd), ("clutter_per_ping", args.clutter)) if v is not None}
    overrides.update(dict(args.settings or ()))
    if path.suffix.lower() == ".csv":
        sonar = Sonar(max_range_m=args.max_range, half_fov_deg=args.half_fov)
        pings, report = read_detections(path, sonar=sonar, crs=args.crs)
        truth = None
        if args.truth is not None:
            from ..track.truth import read_truth

            truth = read_truth(args.truth, pings, sonar=sonar)
        return pings, sonar, _parameters({}, overrides, "--set"), truth, path.stem, report.summary(), None
    scenario = load_scenario(path if path.suffix.lower() == ".toml" or path.is_file() else builtin_scenario_path(source))
    sim = simulate(scenario)
    model = scenario.sonar
    params = _parameters(tracker_model(model), {**scenario.tracker, **overrides}, f"--set or [tracker] of {scenario.name}")
    note = f"{scenario.name}: {len(sim.pings)} pings simulated, {sim.target_detections} target detections, {sim.false_alarms} false alarms"
    return sim.pings, model.sonar, params, sim.truth, scenario.name, note, sim


def run_track(args: argparse.Namespace) -> int:
    """The handler of ``lost track``."""
    pings, sonar, params, truth, name, note, sim = _load(args.input, args)
    print(note)
    out = args.out = args.out or Path("runs") / "track" / name
    with run_folder(out, replace=args.replace, command="track") as folder, warnings_collected() as warnings:
        if args.write_detections and sim is not None:
            from ..track.truth import write_truth

            write_detections(folder / "detections.csv", pings)
            write_truth(folder / "truth.csv", truth)
        run = run_tracker(pings, sonar=sonar, parameters=params, seed=args.seed, progress=progress_bar(len(pings), "tracking"))
        summary = _summary(args, pings, sonar, params, truth, name, run)
        write_tracks_csv(folder / "tracks.csv", run.reports)
        draw_plots(folder, _plots(args, sonar, pings, run, truth), warnings)
        summary["warnings"] = list(warnings)
        write_summary(folder / "summary.json", summary)
    _print(summary, out)
    return 0


def _summary(args: argparse.Namespace, pings, sonar: Sonar, params: TrackerParameters, truth, name: str, run) -> dict:
    summary: dict = {
        "name": name, "input": str(args.input), "pings": len(pings), "detections": int(sum(p.detections for p in pings)),
        "tracker": params.as_dict(), "seed": args.seed, "truth_known": truth is not None,
        "ms_per_ping": float(run.step_ms.mean()), "ms_per_ping_p95": float(np.percentile(run.step_ms, 95)),
        "tentative_tracks": run.tracks_born, "tracks": track_table(run.reports),
        "confirmed_tracks": len({e.track_id for ping in run.estimates for e in ping}),
        "pings_to_lock": None, "false_tracks": None, "gospa_mean": None,
    }
    if truth is not None:
        s = score(run.estimates, truth)
        summary.update(pings_to_lock=s.pings_to_lock, false_tracks=s.false_tracks, gospa_mean=s.gospa_mean,
                       gospa={"localisation": s.gospa_localisation_mean, "missed": s.gospa_missed_mean, "false": s.gospa_false_mean},
                       ospa_mean=s.ospa_mean, siap=s.siap)
    if args.baseline:
        summary["baselines"] = _baseline(pings, sonar, params, truth)
    return summary


def _baseline(pings, sonar: Sonar, params: TrackerParameters, truth) -> dict:
    """Stone Soup's GM-PHD and its JPDA with an M-of-N initiator on the same pings, each scored as the tracker is."""
    from ..track.baseline import run_gm_phd, run_jpda

    baselines = {}
    for name, label, run in (("gm_phd", "Stone Soup GM-PHD (PointProcessMultiTargetTracker)", run_gm_phd),
                             ("jpda", "Stone Soup JPDA with an M-of-N initiator (MultiTargetMixtureTracker)", run_jpda)):
        start = time.perf_counter()
        estimates = run(pings, sonar=sonar, tracker=params)
        entry = {"tracker": label, "ms_per_ping": (time.perf_counter() - start) / len(pings) * 1e3,
                 "confirmed_tracks": len({e.track_id for ping in estimates for e in ping})}
        if truth is not None:
            b = score(estimates, truth)
            entry.update(pings_to_lock=b.pings_to_lock, false_tracks=b.false_tracks, gospa_mean=b.gospa_mean, ospa_mean=b.ospa_mean, siap=b.siap)
        baselines[name] = entry
    return baselines


def _plots(args: argparse.Namespace, sonar: Sonar, pings, run, truth) -> dict:
    from ..track.plots import animate, plot_sector

    truth_xy = None if truth is None else truth.xy
    plots = {"sector.png": lambda path: plot_sector(path, sonar, pings, run.reports, run.clouds, truth_xy=truth_xy)}
    if not args.no_animation:
        plots["tracks.gif"] = lambda path: animate(path, sonar, pings, run.reports, run.clouds, truth_xy=truth_xy)
    return plots


def _print(summary: dict, out: Path) -> None:
    print(f"{summary['confirmed_tracks']} confirmed track(s) of {summary['tentative_tracks']} tentative; "
          f"{summary['ms_per_ping']:.2f} ms per ping (p95 {summary['ms_per_ping_p95']:.2f}) with {summary['tracker']['particles']} particles")
    for t in summary["tracks"]:
        reach = "-" if t["last_time_to_reach_s"] is None else f"{t['last_time_to_reach_s']:.0f} s"
        print(f"  track {t['track_id']:4d}: pings {t['first_ping']}-{t['last_ping']}, {t['class']}, {t['last_speed_mps']:.2f} m/s, "
              f"range {t['last_range_m']:.0f} m, CPA {t['last_cpa_m']:.0f} m, reaches the sonar in {reach}")
    if summary["truth_known"]:
        print(f"pings to lock {summary['pings_to_lock']}, false tracks {summary['false_tracks']}, mean GOSPA {summary['gospa_mean']:.2f} m")
    for b in summary.get("baselines", {}).values():
        extra = f", pings to lock {b['pings_to_lock']}, false tracks {b['false_tracks']}, mean GOSPA {b['gospa_mean']:.2f} m" if "gospa_mean" in b else ""
        print(f"baseline ({b['tracker']}): {b['confirmed_tracks']} track(s), {b['ms_per_ping']:.1f} ms per ping{extra}")
    drawn = [name for name in ("sector.png", "tracks.gif") if (out / name).is_file()]
    print(f"wrote {out}/" + ", ".join(["tracks.csv", *drawn, "summary.json"]))


def register(commands, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``lost track``."""
    sub = commands.add_parser("track", parents=parents, help="track sonar contacts (divers) in recorded detections or a simulated scenario")
    sub.add_argument("input", help="detections CSV, scenario TOML, or a built-in scenario's name (one_diver, two_divers, clutter_hour)")
    output_options(sub, "runs/track/NAME")
    sub.add_argument("--baseline", action="store_true", help="also run Stone Soup's GM-PHD and JPDA on the same pings (slow: ~0.1 s a ping)")
    sub.add_argument("--particles", type=int, default=None, help="search-cloud particles (default 10000)")
    sub.add_argument("--seed", type=int, default=0, help="the tracker's random seed (default 0)")
    sub.add_argument("--pd", type=float, default=None, help="detection probability the tracker assumes (default the scenario's, or 0.9)")
    sub.add_argument("--clutter", type=float, default=None, help="false alarms per ping the tracker assumes (default the scenario's, or 5)")
    settings_option(sub, "a tracker parameter (TrackerParameters)", "--set confirm_existence=0.999 --set bearing_sigma_deg=1.0")
    sub.add_argument("--max-range", type=float, default=500.0, help="with a CSV: the sonar's range, m (default 500)")
    sub.add_argument("--half-fov", type=float, default=45.0, help="with a CSV: half the field of view, degrees (default 45)")
    sub.add_argument("--crs", default=None, help="with a CSV of platform_lat/platform_lon: the projected CRS to work in (default its UTM zone)")
    sub.add_argument("--no-animation", action="store_true", help="skip tracks.gif (the slowest output)")
    sub.add_argument("--truth", type=Path, default=None, help="with a CSV: where the targets really were (layout: lost.host.track.truth), to score the run")
    sub.add_argument("--write-detections", action="store_true", help="with a scenario: also write its pings as detections.csv and its truth as truth.csv")
    sub.set_defaults(handler=run_track)


