"""``lost run`` and ``lost demo``: the navigation on a simulated or recorded tow, into a run folder.

::

    lost run SCENARIO.toml|NAME [--out DIR]                                  a simulated tow
    lost run --log nav.csv --bathy grid.nc [--sonar soundings.csv] [--svp CAST.csv] [--out DIR]
    lost run --survey FILE... --bathy grid.nc [--dr-bias E,N] [--start-offset E,N] [--record-s S] [--window-s S] [--full-window]
                                         [--patch-rule window|behind] [--usbl-fixes FILE]    a recorded multibeam survey (.all, .kmall, GSF)
    lost demo [--out runs/demo]                                              the built-in scenario "demo"

``run`` writes ``track.csv``, ``summary.json``, ``map.png`` and ``error.png`` into ``--out``, whole or not at all
(``--no-plots``: the two figures not drawn, for batch runs).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np

from lost.model.shapes import shape_argument

from ..correlator import BACKENDS
from ..errors import UsageError
from ..grid import Grid
from ..io.navlog import PATCH_CENTRES
from ..io.survey_records import SURVEY_PATCH_RULES
from ..nav import ESTIMATORS, NavParameters, navigate
from ..records import NavRecords
from ..runfolder import run_folder, write_summary
from .common import (
    BACKEND_HELP,
    configure_hardware,
    hardware_options,
    map_uncertainty,
    merge_settings,
    output_options,
    positive_metres,
    progress_bar,
    settings_option,
    warnings_collected,
)

__all__ = ["register", "run_demo", "navigation_options"]


def _estimators(choice: str) -> tuple[str, ...]:
    """``--estimator``: one name of ESTIMATORS, or ``all``."""
    return ESTIMATORS if choice == "all" else (choice,)


def _navigate(records: NavRecords, grid: Grid, params: NavParameters, *, name: str, out: Path, warnings: list[str],
              estimators: tuple[str, ...] = ESTIMATORS, profile=None, profile_source: str | None = None, extra: dict | None = None,
              plots: bool = True) -> dict:
    from ..plotting import draw_plots
    from ..report import run_plots, summarize, write_track_csv

    if profile is None and np.isfinite(records.usbl_travel_time_s).any():
        warnings.append("the records have USBL travel times but no sound-speed profile was given (--svp CAST.csv): "
                        "they are not used; the straight-line slant_range_m is, where there is one")
    start = time.perf_counter()
    result = navigate(records, grid, params, estimators=estimators, progress=progress_bar(len(records), "navigating"), profile=profile)
    elapsed = time.perf_counter() - start
    summary = summarize(result, name=name, parameters=params.as_dict(), run_time_s=elapsed)
    summary["sound_speed_profile"] = profile_source
    summary.update(extra or {})
    write_track_csv(out / "track.csv", result)
    if plots:
        draw_plots(out, run_plots(result, grid, summary), warnings)
    summary["warnings"] = list(warnings)
    write_summary(out / "summary.json", summary)
    return summary


def _print_summary(summary: dict, out: Path) -> None:
    print(f"{summary['name']}: {summary['records']} records, {summary['duration_s']:.0f} s of tow, navigated in {summary['run_time_s']:.2f} s")
    convergence = summary["convergence"]
    if summary["truth_known"]:
        who = "LOST" if convergence["estimator"] == "lost" else convergence["estimator"]
        if convergence["converged"]:
            print(f"{who} converged after {convergence['time_s']:.0f} s from an initial error of {convergence['initial_error_m']:.1f} m")
        else:
            print(f"{who} did not converge (initial error {convergence['initial_error_m']:.1f} m)")
        columns = ("rms_m", "p95_m", "max_m", "nees_in_band", "usable_fraction", "false_fixes", "ms_per_update")
        print(f"{'method':16s} " + " ".join(f"{c:>15s}" for c in columns) + "   (errors after each one's convergence)")
        for method, stats in summary["methods"].items():
            cells = ["-" if stats.get(k) is None else f"{stats[k]:.2f}" if isinstance(stats[k], float) else str(stats[k]) for k in columns]
            print(f"{method:16s} " + " ".join(f"{c:>15s}" for c in cells))
    if "lost" in summary["methods"]:  # the patent pipeline's own counts: without it they would count every record
        print(f"LOST: off-map records {summary['off_map_records']}, records without an MLE {summary['dead_reckoning_records']}")
    _print_map_uncertainty(summary)
    _print_usbl(summary)
    for warning in summary.get("warnings", ()):
        print(f"warning: {warning}")
    drawn = [name for name in ("map.png", "error.png") if (out / name).is_file()]
    print(f"wrote {out}/" + ", ".join(["track.csv", "summary.json", *drawn]))


def _print_map_uncertainty(summary: dict) -> None:
    """One line on where the map's survey error came from, for a recorded map."""
    m = summary.get("map_uncertainty")
    if not m:
        return
    used = "" if m["used"] else f" (not used: {m['not_used_because']})"
    print(f"map uncertainty: {m['source']}, {m['nodes_from_layer']} nodes from the layer, {m['nodes_from_survey_sigma_m']} at "
          f"survey_sigma_m {m['survey_sigma_m']:g} m{used}")


def _print_usbl(summary: dict) -> None:
    """One line on the USBL's share, when the records had one."""
    counts = summary.get("counts", {})
    fixes = {name: stats.get("counts", {}).get("fix_updates", 0) for name, stats in summary["methods"].items() if "counts" in stats}
    traced, unused = counts.get("slant_range_ray_traced", 0), counts.get("usbl_travel_time_without_profile", 0)
    recentred = counts.get("usbl_fix_recentred", 0)
    if not (traced or unused or recentred or any(fixes.values())):
        return
    used = ", ".join(f"{name} {n}" for name, n in fixes.items() if n)
    print(f"USBL: {traced} slant ranges ray-traced ({summary.get('sound_speed_profile')}), {unused} travel times unused for want of a "
          f"profile; fixes used: {used or 'none'}{f', LOST re-centred on {recentred}' if recentred else ''}")


def _parameters(args: argparse.Namespace, base: dict) -> NavParameters:
    """The navigation parameters: ``base`` (a scenario's [navigation]), then --config's, --set, --backend/--matching; strictly validated."""
    from ..config import read_navigation_table
    from ..nav import navigation_parameters

    configure_hardware(args)
    overrides = {key: value for key, value in (("backend", args.backend), ("matching", args.matching)) if value is not None}
    layers = [("navigation", base)]
    if getattr(args, "config", None) is not None:
        layers.append((f"{args.config} [navigation]", read_navigation_table(args.config)))
    layers += [("--set", dict(args.settings or ())), ("--backend/--matching", overrides)]
    merged = merge_settings(layers, NavParameters.__dataclass_fields__, "navigation parameter", navigation_parameters)
    return navigation_parameters(merged)


def _seed(text: str) -> int:
    """A scenario's seed: a whole number of at least 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a seed is a whole number, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"a seed is at least 0, got {value}")
    return value


def _scenario_path(text: str) -> Path:
    from ..scenario import builtin_scenario_path

    path = Path(text)
    # A folder of that name (an earlier run's --out, say) is not a scenario file: the shipped scenario is meant.
    return path if path.suffix == ".toml" or path.is_file() else builtin_scenario_path(text)


def _svp(path: Path | None):
    """``--svp``: the sound-speed profile of a cast CSV (lost.host.usbl.sound), its layers within 5 cm/s of the cast."""
    if path is None:
        return None
    from ..usbl.sound import SoundSpeedProfile, read_cast

    return SoundSpeedProfile.from_cast(read_cast(path), tolerance_m_s=0.05)


def _run_scenario(path: Path, args: argparse.Namespace, out: Path | None) -> int:
    from ..scenario import load_scenario, simulate, usbl_profile

    scenario = load_scenario(path)
    seed = getattr(args, "seed", None)  # lost demo has no --seed
    if seed is not None:
        # a campaign's seed: the scenario drawn anew (its sensors, and its floor and map where it does not fix their seeds)
        scenario = dataclasses.replace(scenario, seed=seed)
    params = _parameters(args, scenario.navigation)
    svp = getattr(args, "svp", None)
    # --svp wins over the scenario's own cast (to see what another profile does to the same replies).
    profile = _svp(svp) if svp is not None else usbl_profile(scenario)
    source = str(svp) if svp is not None else (f"[sensors.usbl] cast {scenario.sensors['usbl'].cast}" if profile is not None else None)
    out = args.out = out or Path("runs") / (scenario.name if seed is None else f"{scenario.name}-seed{seed}")  # args.out: main names it if the run fails
    with run_folder(out, replace=args.replace) as folder, warnings_collected() as warnings:
        grid, records = simulate(scenario)
        usbl = scenario.sensors["usbl"]
        if usbl.enabled and params.reference_depth_m != usbl.transducer_depth_m:
            warnings.append(f"[navigation] reference_depth_m ({params.reference_depth_m:g} m) is not the USBL transducer's depth "
                            f"([sensors.usbl] transducer_depth_m = {usbl.transducer_depth_m:g} m): the rays start at the wrong depth")
        summary = _navigate(records, grid, params, plots=not args.no_plots, name=scenario.name, out=folder, warnings=warnings,
                            estimators=_estimators(args.estimator), profile=profile, profile_source=source)
    _print_summary(summary, out)
    return 0


#: Options of `lost run` that describe recorded files, meaningless with a scenario.
_RECORDED_ONLY = ("sonar", "node_m", "crs", "source_crs", "positive", "nodata")


def _cmd_run(args: argparse.Namespace) -> int:
    if args.list:
        from ..scenario import builtin_descriptions

        for name, description in builtin_descriptions().items():
            print(f"{name:<18} {description}")
        return 0
    survey_options = [f"--{name.replace('_', '-')}" for name in _SURVEY_ONLY if getattr(args, name) is not None]
    if args.seed is not None and args.scenario is None:
        raise UsageError("--seed draws a simulated scenario anew: give a scenario (a recorded tow has no seed)")
    if args.survey:
        if args.scenario is not None or args.log:
            raise UsageError("give one of a scenario, --log or --survey")
        if args.sonar or args.svp:
            raise UsageError("--sonar and --svp belong to a navigation log (--log); a survey's soundings are its own beams")
        if not args.bathy:
            raise UsageError("lost run --survey needs the map: --bathy grid.nc (e.g. made by lost grid)")
        return _run_survey(args)
    if survey_options:
        raise UsageError(f"{', '.join(survey_options)} apply to a recorded survey (--survey FILE...)")
    if args.scenario is not None:
        if args.log or args.bathy:
            raise UsageError("give either a scenario or --log and --bathy, not both")
        grid_options = [f"--{name.replace('_', '-')}" for name in _RECORDED_ONLY if getattr(args, name) is not None]
        if grid_options:
            raise UsageError(f"{', '.join(grid_options)} apply to a recorded tow (--log, --bathy); a scenario sets its map in [terrain]")
        return _run_scenario(_scenario_path(args.scenario), args, args.out)
    if args.log and not args.bathy:
        raise UsageError("--log needs the map it is navigated on: --bathy grid.nc")
    if args.bathy and not args.log:
        raise UsageError("--bathy is the map of a recorded tow: give its navigation log (--log nav.csv) or survey files (--survey FILE...)")
    if not args.log:
        raise UsageError("give a scenario (a TOML file, or a shipped one's name: lost run --list), or --log nav.csv and "
                         "--bathy grid.nc, or --survey FILE... and --bathy grid.nc")
    try:
        from ..io import read_grid
        from ..io.navlog import check_against_map, read_navlog
    except ImportError as error:
        raise ValueError(f"reading recorded tows is not available in this build: {error}") from None
    params = _parameters(args, {})
    profile = _svp(args.svp)
    out = args.out = args.out or Path("runs") / Path(args.log).stem
    with run_folder(out, replace=args.replace) as folder, warnings_collected() as warnings:
        grid = read_grid(args.bathy, node_m=args.node_m, crs=args.crs, source_crs=args.source_crs, positive=args.positive, nodata=args.nodata)
        grid, extra = map_uncertainty(grid, params)
        records, report = read_navlog(args.log, sonar=args.sonar, crs=grid.crs, node_m=grid.node_m,
                                      patch_shape=args.patch_shape, patch_centre=args.patch_centre)
        print(report.summary())
        warnings += [*report.warnings, *check_against_map(records, grid)]
        summary = _navigate(records, grid, params, plots=not args.no_plots, name=Path(args.log).stem, out=folder, warnings=warnings,
                            estimators=_estimators(args.estimator), profile=profile, profile_source=None if args.svp is None else str(args.svp),
                            extra=extra)
    _print_summary(summary, out)
    return 0




#: Options of `lost run` that only a recorded survey (--survey) takes.
_SURVEY_ONLY = ("dr_bias", "start_offset", "record_s", "window_s", "full_window", "patch_rule", "usbl_fixes", "usbl_default_sigma_m")


def _run_survey(args: argparse.Namespace) -> int:
    """``lost run --survey FILE... --bathy GRID``: navigate a recorded multibeam survey against its map."""
    from ..io import read_grid
    from ..io.survey import open_survey
    from ..io.survey_records import DEFAULT_RECORD_S, SurveyRecorder, check_survey_on_map, survey_records

    if args.usbl_default_sigma_m is not None and args.usbl_fixes is None:
        raise UsageError("--usbl-default-sigma-m is the 1 sigma of --usbl-fixes' sentences without error fields: give --usbl-fixes FILE")
    if args.patch_rule == "behind" and args.patch_centre == "soundings":
        raise UsageError("--patch-rule behind centres each patch on its centre ping: --patch-centre soundings cannot be given with it")
    params = _parameters(args, {})
    files = [Path(f) for f in args.survey]
    names = ", ".join(f.name for f in files)
    out = args.out = args.out or Path("runs") / files[0].stem
    with run_folder(out, replace=args.replace) as folder, warnings_collected() as warnings:
        grid = read_grid(args.bathy, node_m=args.node_m, crs=args.crs, source_crs=args.source_crs, positive=args.positive, nodata=args.nodata)
        if grid.crs is None:
            raise ValueError(f"{args.bathy} has no CRS: a survey's positions (latitude, longitude) cannot be placed on it")
        grid, extra = map_uncertainty(grid, params)
        survey = open_survey(files, crs=grid.crs)
        interval = args.record_s if args.record_s is not None else DEFAULT_RECORD_S
        recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=args.patch_shape, interval_s=interval, window_s=args.window_s,
                                  dr_bias_mps=args.dr_bias or (0.0, 0.0), start_offset_m=args.start_offset or (0.0, 0.0),
                                  patch_centre=args.patch_centre, full_window=bool(args.full_window), patch_rule=args.patch_rule or "window")
        records = survey_records(survey, recorder)
        if args.usbl_fixes is not None:
            records, extra["usbl_fixes"] = _survey_usbl_fixes(args.usbl_fixes, records, recorder.epoch_s, grid.crs, args.usbl_default_sigma_m)
        warnings += check_survey_on_map(records, grid, names)
        skipped = {**dict(survey.skipped), **dict(recorder.skipped)}
        extra["survey"] = {"files": [str(f) for f in files], "format": survey.format, "first_ping_utc_s": recorder.epoch_s,
                           "record_s": interval, "window_s": recorder.window_s, "full_window": recorder.full_window, "patch_rule": recorder.patch_rule,
                           "dr_bias_mps": list(recorder.bias),
                           "start_offset_m": list(recorder.start_offset), "skipped": skipped, "notes": dict(survey.notes)}
        extra["survey"]["log"] = _save_survey_log(records, folder, recorder.epoch_s)
        chosen = f"of the last {recorder.window_s:g} s of pings" if recorder.patch_rule == "window" else f"behind, of pings up to {recorder.window_s:g} s back"
        print(f"{names}: {len(records)} records of {interval:g} s, patches {chosen}"
              + "".join(f"\n  skipped: {n} {reason}" for reason, n in skipped.items()))
        summary = _navigate(records, grid, params, plots=not args.no_plots, name=files[0].stem, out=folder, warnings=warnings,
                            estimators=_estimators(args.estimator), extra=extra)
    _print_summary(summary, out)
    return 0


def _survey_usbl_fixes(path: Path, records, epoch_s: float, crs: str, default_sigma_m: float | None):
    """``--usbl-fixes``: the file's fixes (the lines `lost serve` receives) in the records whose intervals hold them, as served."""
    from collections import Counter

    from ..io.crs import transformer
    from ..live.usbl import place_usbl_fixes, placed_fix, read_usbl_fixes

    fixes, counts = read_usbl_fixes(path, sonar_time_s=epoch_s, default_sigma_m=default_sigma_m)
    to_map = transformer("EPSG:4326", crs)
    placed = Counter()
    records, used = place_usbl_fixes(records, epoch_s, [placed_fix(fix, to_map) for fix in fixes], placed)
    print(f"{path.name}: {len(fixes)} USBL fixes, {int(used.sum())} used in {int((used > 0).sum())} records"
          + "".join(f"\n  {reason}: {n}" for reason, n in sorted(placed.items()) if "not used" in reason or "dropped" in reason))
    return records, {"file": str(path), "fixes": len(fixes), "read": dict(counts), "placed": dict(placed)}


def _save_survey_log(records, folder: Path, epoch_utc_s: float) -> dict:
    """The survey's records as a navigation log in the run folder (``records.csv``, ``records_sonar.csv``), which
    ``lost run --log records.csv --sonar records_sonar.csv`` on the same map and ``--patch-shape`` navigates alike."""
    from ..io.navlog import write_navlog

    sonar = SURVEY_LOG[1] if any(patch is not None for patch in records.sonar) else None
    write_navlog(records, folder / SURVEY_LOG[0], sonar=None if sonar is None else folder / sonar, epoch_utc_s=epoch_utc_s)
    return {"log": SURVEY_LOG[0], "sonar": sonar}


#: The navigation log a survey run writes of its records: the log, its sonar side file.
SURVEY_LOG = ("records.csv", "records_sonar.csv")


def _east_north(text: str) -> tuple[float, float]:
    """``E,N``: two finite numbers."""
    try:
        east, north = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected two numbers E,N (east, north), got {text!r}") from None
    if not (np.isfinite(east) and np.isfinite(north)):
        raise argparse.ArgumentTypeError(f"expected two finite numbers E,N, got {text!r}")
    return east, north


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not (np.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return value


def run_demo(args: argparse.Namespace) -> int:
    from ..scenario import builtin_scenario_path

    if args.out is None:
        args.out, args.replace = Path("runs") / "demo", True  # the demo's own folder holds only the demo: running it again replaces it
    return _run_scenario(builtin_scenario_path("demo"), args, args.out)


def navigation_options(sub: argparse.ArgumentParser, out_default: str = "runs/NAME") -> None:
    output_options(sub, out_default)
    sub.add_argument("--backend", choices=sorted(BACKENDS), default=None, help=f"{BACKEND_HELP} (default software)")
    hardware_options(sub)
    sub.add_argument("--matching", choices=("patch", "point"), default=None, help="MLE form (default patch)")
    sub.add_argument("--estimator", choices=(*ESTIMATORS, "all"), default="all",
                     help="the LOST patent pipeline, the point-mass filter, the particle filter, or all three on the same records (default)")
    settings_option(sub, "a navigation parameter (NavParameters), over the scenario's [navigation]",
                    "--set u=0.005 --set cross_damping_per_s=none")


def register(commands, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``lost run`` and ``lost demo``."""
    run = commands.add_parser("run", parents=parents, help="navigate a simulated or recorded tow")
    run.add_argument("scenario", nargs="?", help="scenario TOML file, or a built-in scenario's name")
    run.add_argument("--list", action="store_true", help="list the built-in scenarios with their descriptions, and stop")
    run.add_argument("--seed", type=_seed, default=None, metavar="N",
                     help="run the scenario with this seed (a campaign's seed: its sensors, and its floor and map unless it fixes their seeds)")
    run.add_argument("--log", help="navigation log CSV (lost.host.navlog)")
    run.add_argument("--bathy", help="bathymetry grid file (lost.host.io.read_grid)")
    run.add_argument("--sonar", help="sonar soundings side file of the log")
    run.add_argument("--survey", nargs="+", metavar="FILE", help="a recorded multibeam survey (Kongsberg .all/.kmall, GSF) to navigate "
                     "against --bathy: its positions are the truth, the navigation dead-reckons from their velocity")
    run.add_argument("--dr-bias", type=_east_north, default=None, metavar="E,N",
                     help="--survey: velocity bias added to the dead reckoning, m/s east, north (default 0,0)")
    run.add_argument("--start-offset", type=_east_north, default=None, metavar="E,N",
                     help="--survey: the navigation's start less the file's first position, m east, north (default 0,0)")
    run.add_argument("--record-s", type=_seconds, default=None, metavar="SECONDS", help="--survey: seconds of pings per record (default 5)")
    run.add_argument("--window-s", type=_seconds, default=None, metavar="SECONDS",
                     help="--survey: seconds of pings up to a record that make its patch (default --record-s)")
    run.add_argument("--full-window", action="store_true", default=None,
                     help="--survey: no patch until --window-s seconds of pings are in (a window still filling is a strip of the swath)")
    run.add_argument("--patch-rule", choices=SURVEY_PATCH_RULES, default=None,
                     help="--survey: the pings of a record's patch: the last --window-s seconds (window, the default) or a swath "
                          "scenario's real-time rule (behind: centred on the latest ping half a patch diagonal behind, looked for "
                          "at most --window-s back)")
    run.add_argument("--usbl-fixes", type=Path, default=None, metavar="FILE",
                     help="--survey: USBL fixes, a line each as lost serve receives them (JSON usbl lines, $PSONLLD, $PSIMSSB), "
                          "each in the record whose interval holds it")
    run.add_argument("--usbl-default-sigma-m", type=positive_metres, default=None, metavar="METRES",
                     help="--usbl-fixes: the 1 sigma of a $PSONLLD/$PSIMSSB fix without error fields, as lost serve's "
                          "usbl_default_sigma_m (default: such fixes refused, counted)")
    run.add_argument("--node-m", type=positive_metres, default=None, metavar="METRES",
                     help="node spacing of the map (and of the sonar patches), metres (default: the grid file's)")
    run.add_argument("--crs", default=None, help="projected CRS to navigate in (default: the grid's own, or its UTM zone)")
    run.add_argument("--source-crs", default=None, help="CRS of the grid file's coordinates when it declares none")
    run.add_argument("--positive", choices=("up", "down"), default=None,
                     help="the grid holds elevation (up, as GEBCO) or depth (down); default: its metadata, else its data's sign")
    run.add_argument("--nodata", type=float, default=None, metavar="VALUE",
                     help="a value of the grid file that marks a hole, when the file declares none (e.g. -32768)")
    run.add_argument("--patch-shape", type=shape_argument, default=(10, 10), metavar="ROWSxCOLS",
                     help="nodes of the sonar patch the soundings are gridded into (default 10x10)")
    run.add_argument("--patch-centre", choices=PATCH_CENTRES, default="vehicle",
                     help="centre of a record's patch when the log has no patch_east_m/patch_north_m: the vehicle "
                          "(default) or the middle of its soundings (a swath gathered in real time, behind the vehicle)")
    run.add_argument("--config", type=Path, default=None, metavar="FILE",
                     help="navigation parameters from the [navigation] table of FILE (a scenario file), over a scenario's own; --set wins")
    run.add_argument("--svp", type=Path, default=None, metavar="CAST.csv",
                     help="sound-speed cast (lost.host.usbl.sound's CSV): the log's usbl_travel_time_s is ray-traced into the "
                          "slant range, which wins over slant_range_m; with a scenario, over its [sensors.usbl] cast")
    run.add_argument("--no-plots", action="store_true", help="write the track and the summary only: no map.png, no error.png")
    navigation_options(run)
    run.set_defaults(handler=_cmd_run)
