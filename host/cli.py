"""The ``lost`` command: run the navigation on a scenario or a recorded tow, the demo, the correlator on files.

::

    lost run SCENARIO.toml [--out DIR]                  a simulated tow (a file, or a built-in name)
    lost run --log nav.csv --bathy grid.nc [--sonar soundings.csv] [--svp CAST.csv] [--out DIR]
    lost demo [--out runs/demo]                         the built-in scenario "demo"
    lost correlate MAP PATCH                            best fit and runner-up of a patch on a map
    lost track DETECTIONS.csv|SCENARIO [--out DIR]      sonar contact tracking (lost.host.track.cli)
    lost usbl LOG.csv --svp CAST.csv | SCENARIO         INS+USBL positioning of the towfish (lost.host.usbl.cli)

Every command takes ``--backend``; ``--backend fpga --port /dev/ttyUSB0`` runs the correlator on the
board, ``--backend rtl [--variant NAME]`` on the device co-simulated on Verilator.

``run`` writes ``track.csv``, ``summary.json``, ``map.png`` and ``error.png`` into ``--out``, whole or not at
all (``lost.host.runfolder``): an earlier run there is replaced only with ``--replace``.

Exit codes: 0 done; 1 an error in the inputs or the outputs (one line on stderr naming the file or
field; ``--debug`` adds the traceback); 2 a usage error (options); 130 interrupted (Ctrl-C or
SIGTERM), the output folder left as it was.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import signal
import sys
import time
import tomllib
import traceback
from pathlib import Path

import numpy as np

from lost.model.shapes import shape_argument

from .correlator import BACKENDS, configure_backend, correlation
from .errors import UsageError
from .grid import Grid
from .io.navlog import PATCH_CENTRES
from .nav import ESTIMATORS, NavParameters, PreparedMap, navigate
from .records import NavRecords
from .runfolder import describe_untouched, run_folder
from .usbl.cli import add_usbl_command

__all__ = ["main", "UsageError", "EXIT_OK", "EXIT_ERROR", "EXIT_USAGE", "EXIT_INTERRUPTED"]

EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130



#: Runs longer than this many records show a progress bar.
PROGRESS_ITEMS = 1000


def progress_bar(total: int, description: str):
    """A progress bar on stderr over ``total`` items (records, pings), or None for a run too short to need one."""
    if total <= PROGRESS_ITEMS:
        return None
    from rich.console import Console
    from rich.progress import track

    console = Console(stderr=True)
    return lambda iterable: track(iterable, total=total, description=description, console=console, transient=True)


class _Collector(logging.Handler):
    """Keeps the warnings of ``lost.host`` (a grid's sign guessed from its data, ...) for the run's report."""

    def __init__(self) -> None:
        super().__init__(level=logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


@contextlib.contextmanager
def _warnings_collected():
    """Yield the list the warnings of the run go to (instead of stderr: the report shows them)."""
    collector, logger = _Collector(), logging.getLogger("lost.host")
    logger.addHandler(collector)
    try:
        yield collector.messages
    finally:
        logger.removeHandler(collector)


def _estimators(choice: str) -> tuple[str, ...]:
    """``--estimator``: one name of ESTIMATORS, or ``all``."""
    return ESTIMATORS if choice == "all" else (choice,)


def _navigate(records: NavRecords, grid: Grid, params: NavParameters, *, name: str, out: Path, warnings: list[str],
              estimators: tuple[str, ...] = ESTIMATORS, profile=None, profile_source: str | None = None) -> dict:
    from .report import plot_run, summarize, write_summary, write_track_csv

    if profile is None and np.isfinite(records.usbl_travel_time_s).any():
        warnings.append("the records have USBL travel times but no sound-speed profile was given (--svp CAST.csv): "
                        "they are not used; the straight-line slant_range_m is, where there is one")
    start = time.perf_counter()
    result = navigate(records, grid, params, estimators=estimators, progress=progress_bar(len(records), "navigating"), profile=profile)
    elapsed = time.perf_counter() - start
    summary = summarize(result, name=name, parameters=params.as_dict(), run_time_s=elapsed)
    summary["sound_speed_profile"] = profile_source
    summary["warnings"] = list(warnings)
    write_track_csv(out / "track.csv", result)
    write_summary(out / "summary.json", summary)
    plot_run(out, result, grid, summary)
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
    print(f"off-map records: {summary['off_map_records']}; records without an MLE: {summary['dead_reckoning_records']}")
    _print_usbl(summary)
    for warning in summary.get("warnings", ()):
        print(f"warning: {warning}")
    print(f"wrote {out}/track.csv, summary.json, map.png" + (", error.png" if summary["truth_known"] else ""))


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


def setting_argument(text: str) -> tuple[str, object]:
    """``NAME=VALUE`` of ``--set`` (``lost`` and ``lost track``): VALUE as a TOML value (``0.05``, ``true``, ``[0, 200]``,
    ``"cable"``), ``none`` for None, a bare word as a string; the settings' strict schema judges the type after."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    if value.strip().lower() == "none":
        return name.strip(), None
    try:
        return name.strip(), tomllib.loads(f"value = {value}")["value"]
    except tomllib.TOMLDecodeError:
        # A bare word (cable, software) is a string.
        return name.strip(), value.strip()


def _parameters(args: argparse.Namespace, base: dict) -> NavParameters:
    """The navigation parameters: ``base`` (a scenario's [navigation]), then --config's, --set, --backend/--matching; strictly validated."""
    from .config import ConfigError, navigation_parameters, read_navigation_table

    _configure_hardware(args)
    overrides = {key: value for key, value in (("backend", args.backend), ("matching", args.matching)) if value is not None}
    settings = dict(args.settings or ())
    fields = set(NavParameters.__dataclass_fields__)
    unknown = sorted(set(settings) - fields)
    if unknown:
        raise UsageError(f"--set names no navigation parameter: {', '.join(unknown)} (known: {', '.join(sorted(fields))})")
    layers = [("navigation", base)]
    if getattr(args, "config", None) is not None:
        layers.append((f"{args.config} [navigation]", read_navigation_table(args.config)))
    layers += [("--set", settings), ("--backend/--matching", overrides)]
    merged: dict = {}
    for where, table in layers:
        # Each layer alone first, so an error names where its value came from; a bad option value is a usage error.
        try:
            navigation_parameters(table, where)
        except ConfigError as error:
            raise (UsageError(str(error)) if where.startswith("--") else error) from None
        merged.update(table)
    return navigation_parameters(merged)


def _positive_metres(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive number of metres, got {text!r}")
    return value


def _scenario_path(text: str) -> Path:
    from .scenario import builtin_scenario_path

    path = Path(text)
    return path if path.suffix == ".toml" or path.exists() else builtin_scenario_path(text)


def _svp(path: Path | None):
    """``--svp``: the sound-speed profile of a cast CSV (lost.host.usbl.sound), its layers within 5 cm/s of the cast."""
    if path is None:
        return None
    from .usbl.sound import SoundSpeedProfile, read_cast

    return SoundSpeedProfile.from_cast(read_cast(path), tolerance_m_s=0.05)


def _run_scenario(path: Path, args: argparse.Namespace, out: Path | None) -> int:
    from .scenario import load_scenario, simulate, usbl_profile

    scenario = load_scenario(path)
    params = _parameters(args, scenario.navigation)
    svp = getattr(args, "svp", None)
    # --svp wins over the scenario's own cast (to see what another profile does to the same replies).
    profile = _svp(svp) if svp is not None else usbl_profile(scenario)
    source = str(svp) if svp is not None else (f"[sensors.usbl] cast {scenario.sensors['usbl'].cast}" if profile is not None else None)
    out = args.out = out or Path("runs") / scenario.name  # args.out: main names it if the run fails
    with run_folder(out, replace=args.replace) as folder, _warnings_collected() as warnings:
        grid, records = simulate(scenario)
        usbl = scenario.sensors["usbl"]
        if usbl.enabled and params.reference_depth_m != usbl.transducer_depth_m:
            warnings.append(f"[navigation] reference_depth_m ({params.reference_depth_m:g} m) is not the USBL transducer's depth "
                            f"([sensors.usbl] transducer_depth_m = {usbl.transducer_depth_m:g} m): the rays start at the wrong depth")
        summary = _navigate(records, grid, params, name=scenario.name, out=folder, warnings=warnings, estimators=_estimators(args.estimator),
                            profile=profile, profile_source=source)
    _print_summary(summary, out)
    return 0


#: Options of `lost run` that describe recorded files, meaningless with a scenario.
_RECORDED_ONLY = ("sonar", "node_m", "crs", "source_crs", "positive", "nodata")


def _cmd_run(args: argparse.Namespace) -> int:
    if args.scenario is not None:
        if args.log or args.bathy:
            raise UsageError("give either a scenario or --log and --bathy, not both")
        grid_options = [f"--{name.replace('_', '-')}" for name in _RECORDED_ONLY if getattr(args, name) is not None]
        if grid_options:
            raise UsageError(f"{', '.join(grid_options)} apply to a recorded tow (--log, --bathy); a scenario sets its map in [terrain]")
        return _run_scenario(_scenario_path(args.scenario), args, args.out)
    if not (args.log and args.bathy):
        raise UsageError("lost run needs a scenario file, or both --log nav.csv and --bathy grid")
    try:
        from .io import read_grid
        from .io.navlog import check_against_map, read_navlog
    except ImportError as error:
        raise ValueError(f"reading recorded tows is not available in this build: {error}") from None
    params = _parameters(args, {})
    profile = _svp(args.svp)
    out = args.out = args.out or Path("runs") / Path(args.log).stem
    with run_folder(out, replace=args.replace) as folder, _warnings_collected() as warnings:
        grid = read_grid(args.bathy, node_m=args.node_m, crs=args.crs, source_crs=args.source_crs, positive=args.positive, nodata=args.nodata)
        records, report = read_navlog(args.log, sonar=args.sonar, crs=grid.crs, node_m=grid.node_m,
                                      patch_shape=args.patch_shape, patch_centre=args.patch_centre)
        print(report.summary())
        warnings += [*report.warnings, *check_against_map(records, grid)]
        summary = _navigate(records, grid, params, name=Path(args.log).stem, out=folder, warnings=warnings,
                            estimators=_estimators(args.estimator), profile=profile, profile_source=None if args.svp is None else str(args.svp))
    _print_summary(summary, out)
    return 0


def _cmd_demo(args: argparse.Namespace) -> int:
    from .scenario import builtin_scenario_path

    return _run_scenario(builtin_scenario_path("demo"), args, args.out)


def _load_patch(path: Path) -> np.ndarray:
    if path.suffix == ".npy":
        patch = np.load(path, allow_pickle=False)
    elif path.suffix == ".npz":
        with np.load(path, allow_pickle=False) as data:
            key = "depth_m" if "depth_m" in data.files else data.files[0] if len(data.files) == 1 else None
            if key is None:
                raise ValueError(f"{path.name} holds {data.files}; name the patch array 'depth_m'")
            patch = data[key]
    elif path.suffix in (".csv", ".txt"):
        patch = np.genfromtxt(path, delimiter=",", dtype=np.float64)  # empty cells read as NaN: no beam
    else:
        raise ValueError(f"a patch must be .npy, .npz or .csv of depths in metres, got {path.name}")
    patch = np.asarray(patch, dtype=np.float64)
    if patch.ndim != 2:
        raise ValueError(f"{path.name} holds a {patch.ndim}-D array; a patch is 2-D")
    return patch


def _configure_hardware(args: argparse.Namespace) -> None:
    """``--port`` (and ``--baud``) make the fpga backend; ``--variant`` picks the co-simulated device's."""
    backend = getattr(args, "backend", None)
    port, variant = getattr(args, "port", None), getattr(args, "variant", None)
    if port and backend != "fpga":
        raise UsageError("--port is for --backend fpga")
    if variant and backend != "rtl":
        raise UsageError("--variant is for --backend rtl")
    if backend == "fpga":
        if not port:
            raise UsageError("--backend fpga needs --port (the board's serial port, e.g. /dev/ttyUSB0)")
        configure_backend("fpga", port=port, baud=args.baud)
    elif backend == "rtl" and variant:
        configure_backend("rtl", variant=variant)


def _cmd_correlate(args: argparse.Namespace) -> int:
    from .io import read_grid

    grid = read_grid(args.map)
    prepared = PreparedMap(grid=grid, lsb_m=args.lsb_m)
    words, mask, dropped = prepared.quantize_patch(_load_patch(args.patch))
    if not mask.any():
        raise ValueError(f"{args.patch} has no finite depth inside the map's word range")
    _configure_hardware(args)
    start = time.perf_counter()
    result = correlation(prepared.words, words, mask=mask, mean_compensation=not args.no_mean_compensation,
                         backend=args.backend, holes=prepared.holes, exclusion_radius=args.exclusion_radius)
    elapsed_ms = (time.perf_counter() - start) * 1e3
    h, w = words.shape

    def where(i: int, j: int) -> str:
        x, y = grid.xy(i + (h - 1) / 2, j + (w - 1) / 2)
        return f"(i, j) = ({i}, {j})   centre x = {float(x):.1f} m, y = {float(y):.1f} m"

    def placement(p) -> dict | None:
        return None if p is None else {"i": p.i, "j": p.j, "value": int(p.value)}

    summary = {
        "map": str(args.map), "patch": str(args.patch), "backend": args.backend, "lsb_m": prepared.lsb_m,
        "valid_nodes": int(mask.sum()), "dropped_out_of_range": dropped,
        "excluded_placements": int((~result.valid).sum()), "valid_placements": int(result.valid.sum()),
        "best": placement(result.best), "runner_up": placement(result.runner_up), "best_from": result.best_from,
        "device_cycles": result.cycles,
    }
    if args.json:
        print(json.dumps(summary))
        return 0
    print(f"map {grid.shape[0]} x {grid.shape[1]} at {grid.node_m:g} m nodes, patch {h} x {w} ({int(mask.sum())} valid), "
          f"{prepared.lsb_m:g} m depth step, backend {args.backend!r}: {elapsed_ms:.2f} ms"
          + ("" if result.cycles is None else f", {result.cycles} device cycles"))
    if result.best is None:
        print(f"no valid placement: every one of the {result.valid.size} placements touches a hole of the map")
        return 0
    best, ru = result.best, result.runner_up
    print(f"best fit   {where(best.i, best.j)}   V = {best.value}"
          + (f"   ({summary['excluded_placements']} placements touching holes excluded)" if summary["excluded_placements"] else ""))
    if ru is None:
        print(f"runner-up  none farther than {result.exclusion_radius} nodes")
    else:
        print(f"runner-up  {where(ru.i, ru.j)}   V = {ru.value}   ratio {ru.value / max(best.value, 1):.2f}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="lost", description=__doc__.splitlines()[0].replace("``", ""))
    # SUPPRESS on both levels, so `lost --debug run` and `lost run --debug` both work (a subparser's
    # default would otherwise overwrite the top level's value).
    debug = argparse.ArgumentParser(add_help=False)
    debug.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show the traceback of an error")
    parser.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show the traceback of an error")
    commands = parser.add_subparsers(dest="command", required=True)

    def hardware_options(sub: argparse.ArgumentParser) -> None:
        sub.add_argument("--port", default=None, help="serial port of the board, for --backend fpga (e.g. /dev/ttyUSB0)")
        sub.add_argument("--baud", type=int, default=3_000_000, help="the board's UART rate (default 3000000)")
        sub.add_argument("--variant", default=None, help="gateware variant of the co-simulated device, for --backend rtl "
                                                          "(default window_correlator_l1)")

    def navigation_options(sub: argparse.ArgumentParser) -> None:
        sub.add_argument("--out", type=Path, default=None, help="output folder (default runs/NAME), written whole or not at all")
        sub.add_argument("--replace", action="store_true", help="replace an earlier run in --out (whole); without it such a folder is refused")
        sub.add_argument("--backend", choices=sorted(BACKENDS), default=None, help="correlator backend (default software)")
        hardware_options(sub)
        sub.add_argument("--matching", choices=("patch", "point"), default=None, help="MLE form (default patch)")
        sub.add_argument("--estimator", choices=(*ESTIMATORS, "all"), default="all",
                         help="the LOST patent pipeline, the point-mass filter, the particle filter, or all three on the same records (default)")
        sub.add_argument("--set", dest="settings", type=setting_argument, action="append", metavar="NAME=VALUE",
                         help="a navigation parameter (NavParameters), over the scenario's [navigation]; repeatable; "
                              "VALUE is TOML, or none for the patent's default (e.g. --set u=0.005 --set cross_damping_per_s=none)")

    run = commands.add_parser("run", parents=[debug], help="navigate a simulated or recorded tow")
    run.add_argument("scenario", nargs="?", help="scenario TOML file, or a built-in scenario's name")
    run.add_argument("--log", help="navigation log CSV (lost.host.navlog)")
    run.add_argument("--bathy", help="bathymetry grid file (lost.host.io.read_grid)")
    run.add_argument("--sonar", help="sonar soundings side file of the log")
    run.add_argument("--node-m", type=_positive_metres, default=None, metavar="METRES",
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
    navigation_options(run)
    run.set_defaults(handler=_cmd_run)

    demo = commands.add_parser("demo", parents=[debug], help="run the built-in scenario into runs/demo")
    navigation_options(demo)
    demo.set_defaults(handler=_cmd_demo, out=None)

    corr = commands.add_parser("correlate", parents=[debug], help="correlate a sonar patch against a map file")
    corr.add_argument("map", type=Path, help="map: .npz (write_npz) or any grid read_grid reads")
    corr.add_argument("patch", type=Path, help="patch of depths in metres: .npy, .npz or .csv (empty cell = no beam)")
    corr.add_argument("--backend", choices=sorted(BACKENDS), default="software")
    hardware_options(corr)
    corr.add_argument("--no-mean-compensation", action="store_true", help="plain SAD instead of Nygren's eq. 8.1")
    corr.add_argument("--exclusion-radius", type=int, default=None, help="runner-up exclusion, nodes (default half the patch)")
    corr.add_argument("--lsb-m", type=float, default=None, help="depth word step (default: chosen from the map)")
    corr.add_argument("--json", action="store_true", help="print one JSON object")
    corr.set_defaults(handler=_cmd_correlate)

    add_usbl_command(commands)  # lost usbl: INS+USBL positioning (host/usbl/cli.py)
    from .track.cli import add_track_command

    add_track_command(commands)
    return parser


@contextlib.contextmanager
def _sigterm_interrupts():
    """SIGTERM (a job scheduler's stop, ``kill``) unwinds like Ctrl-C, so a run's temporary folder is cleaned up."""
    def interrupt(signum, frame):
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, interrupt)
    except ValueError:  # not the main thread: leave the signal alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _exit_code(error: BaseException) -> int:
    if isinstance(error, KeyboardInterrupt):
        return EXIT_INTERRUPTED
    return EXIT_USAGE if isinstance(error, UsageError) else EXIT_ERROR


def _one_line(error: BaseException) -> str:
    """The error as one line: the message itself for the errors a user causes, with the class for the others."""
    text = " ".join(str(error).split()) or type(error).__name__
    if isinstance(error, (ValueError, OSError)):
        return text
    return f"internal error ({type(error).__name__}: {text}); please report it with the output of --debug"


def main(argv: list[str] | None = None) -> int:
    """Run the ``lost`` command; returns the exit code (argparse's own usage errors raise ``SystemExit(2)``)."""
    args = build_parser().parse_args(argv)
    if args.command == "demo" and args.out is None:
        # The demo's own folder holds only the demo: running it again replaces it.
        args.out, args.replace = Path("runs") / "demo", True
    try:
        with _sigterm_interrupts():
            return args.handler(args)
    except (Exception, KeyboardInterrupt) as error:
        if getattr(args, "debug", False):
            traceback.print_exc(file=sys.stderr)
        if isinstance(error, KeyboardInterrupt):
            message = "interrupted"
        else:
            message = _one_line(error)
        out = getattr(args, "out", None)
        if out is not None and args.command in ("run", "demo") and not isinstance(error, UsageError):
            message += f"; {describe_untouched(Path(out))}"
        print(f"lost {args.command}: {message}", file=sys.stderr)
        return _exit_code(error)


if __name__ == "__main__":
    raise SystemExit(main())
