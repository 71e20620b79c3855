"""The ``lost`` command: run the navigation on a scenario or a recorded tow, the demo, the correlator on files.

::

    lost run SCENARIO.toml [--out DIR]                  a simulated tow (a file, or a built-in name)
    lost run --log nav.csv --bathy grid.nc [--sonar soundings.csv] [--out DIR]
    lost demo [--out runs/demo]                         the built-in scenario "demo"
    lost correlate MAP PATCH                            best fit and runner-up of a patch on a map

Every command takes ``--backend``; ``--backend fpga --port /dev/ttyUSB0`` runs the correlator on the
board, ``--backend rtl [--variant NAME]`` on the device co-simulated on Verilator.

``run`` writes ``track.csv``, ``summary.json``, ``map.png`` and ``error.png`` into ``--out``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import tomllib
from pathlib import Path

import numpy as np

from lost.model.shapes import shape_argument

from .correlator import BACKENDS, configure_backend, correlation
from .grid import Grid
from .nav import NavParameters, PreparedMap, run_lost
from .navlog import PATCH_CENTRES
from .records import NavRecords

__all__ = ["main"]

#: Runs longer than this many records show a progress bar.
PROGRESS_RECORDS = 1000


def _progress(total: int):
    if total <= PROGRESS_RECORDS:
        return None
    from rich.console import Console
    from rich.progress import track

    console = Console(stderr=True)
    return lambda iterable: track(iterable, total=total, description="navigating", console=console, transient=True)


def _navigate(records: NavRecords, grid: Grid, params: NavParameters, *, name: str, out: Path) -> dict:
    from .report import plot_run, summarize, write_summary, write_track_csv

    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    result = run_lost(records, grid, params, progress=_progress(len(records)))
    elapsed = time.perf_counter() - start
    summary = summarize(result, name=name, parameters=params.as_dict(), run_time_s=elapsed)
    write_track_csv(out / "track.csv", result)
    write_summary(out / "summary.json", summary)
    plot_run(out, result, grid, summary)
    return summary


def _print_summary(summary: dict, out: Path) -> None:
    print(f"{summary['name']}: {summary['records']} records, {summary['duration_s']:.0f} s of tow, navigated in {summary['run_time_s']:.2f} s")
    convergence = summary["convergence"]
    if summary["truth_known"]:
        if convergence["converged"]:
            print(f"LOST converged after {convergence['time_s']:.0f} s from an initial error of {convergence['initial_error_m']:.1f} m")
        else:
            print(f"LOST did not converge (initial error {convergence['initial_error_m']:.1f} m)")
        print(f"{'method':16s} {'rms_m':>9s} {'p95_m':>9s} {'max_m':>9s}   (after convergence)")
        for method, stats in summary["methods"].items():
            cells = ["-" if stats[k] is None else f"{stats[k]:.2f}" for k in ("rms_m", "p95_m", "max_m")]
            print(f"{method:16s} {cells[0]:>9s} {cells[1]:>9s} {cells[2]:>9s}")
    print(f"off-map records: {summary['off_map_records']}; records without an MLE: {summary['dead_reckoning_records']}")
    print(f"wrote {out}/track.csv, summary.json, map.png" + (", error.png" if summary["truth_known"] else ""))


def _setting(text: str) -> tuple[str, object]:
    """``NAME=VALUE`` of ``--set``: VALUE as a TOML value (``0.05``, ``true``, ``[0, 200]``, ``"cable"``), ``none`` for None."""
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
    _configure_hardware(args)
    overrides = {key: value for key, value in (("backend", args.backend), ("matching", args.matching)) if value is not None}
    settings = dict(args.settings or ())
    fields = set(NavParameters.__dataclass_fields__)
    unknown = sorted(set(settings) - fields)
    if unknown:
        raise ValueError(f"--set names no navigation parameter: {', '.join(unknown)} (known: {', '.join(sorted(fields))})")
    try:
        return NavParameters(**{**base, **settings, **overrides})
    except TypeError as error:
        raise ValueError(f"[navigation] has a field NavParameters does not know: {error}") from None


def _scenario_path(text: str) -> Path:
    from .scenario import builtin_scenario_path

    path = Path(text)
    return path if path.suffix == ".toml" or path.exists() else builtin_scenario_path(text)


def _run_scenario(path: Path, args: argparse.Namespace, out: Path | None) -> int:
    from .scenario import load_scenario, simulate

    scenario = load_scenario(path)
    grid, records = simulate(scenario)
    out = out or Path("runs") / scenario.name
    summary = _navigate(records, grid, _parameters(args, scenario.navigation), name=scenario.name, out=out)
    _print_summary(summary, out)
    return 0


def _cmd_run(args: argparse.Namespace) -> int:
    if args.scenario is not None:
        if args.log or args.bathy:
            raise ValueError("give either a scenario or --log and --bathy, not both")
        return _run_scenario(_scenario_path(args.scenario), args, args.out)
    if not (args.log and args.bathy):
        raise ValueError("lost run needs a scenario file, or both --log nav.csv and --bathy grid")
    try:
        from .io import read_grid
        from .navlog import read_navlog
    except ImportError as error:
        raise ValueError(f"reading recorded tows is not available in this build: {error}") from None
    grid = read_grid(args.bathy)
    records, report = read_navlog(args.log, sonar=args.sonar, crs=grid.crs, node_m=grid.node_m,
                                  patch_shape=args.patch_shape, patch_centre=args.patch_centre)
    print(report.summary())
    out = args.out or Path("runs") / Path(args.log).stem
    summary = _navigate(records, grid, _parameters(args, {}), name=Path(args.log).stem, out=out)
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
        raise ValueError("--port is for --backend fpga")
    if variant and backend != "rtl":
        raise ValueError("--variant is for --backend rtl")
    if backend == "fpga":
        if not port:
            raise ValueError("--backend fpga needs --port (the board's serial port, e.g. /dev/ttyUSB0)")
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
    commands = parser.add_subparsers(dest="command", required=True)

    def hardware_options(sub: argparse.ArgumentParser) -> None:
        sub.add_argument("--port", default=None, help="serial port of the board, for --backend fpga (e.g. /dev/ttyUSB0)")
        sub.add_argument("--baud", type=int, default=3_000_000, help="the board's UART rate (default 3000000)")
        sub.add_argument("--variant", default=None, help="gateware variant of the co-simulated device, for --backend rtl "
                                                          "(default window_correlator_l1)")

    def navigation_options(sub: argparse.ArgumentParser) -> None:
        sub.add_argument("--out", type=Path, default=None, help="output folder (default runs/NAME)")
        sub.add_argument("--backend", choices=sorted(BACKENDS), default=None, help="correlator backend (default software)")
        hardware_options(sub)
        sub.add_argument("--matching", choices=("patch", "point"), default=None, help="MLE form (default patch)")
        sub.add_argument("--set", dest="settings", type=_setting, action="append", metavar="NAME=VALUE",
                         help="a navigation parameter (NavParameters), over the scenario's [navigation]; repeatable; "
                              "VALUE is TOML, or none for the patent's default (e.g. --set u=0.005 --set cross_damping_per_s=none)")

    run = commands.add_parser("run", help="navigate a simulated or recorded tow")
    run.add_argument("scenario", nargs="?", help="scenario TOML file, or a built-in scenario's name")
    run.add_argument("--log", help="navigation log CSV (lost.host.navlog)")
    run.add_argument("--bathy", help="bathymetry grid file (lost.host.io.read_grid)")
    run.add_argument("--sonar", help="sonar soundings side file of the log")
    run.add_argument("--patch-shape", type=shape_argument, default=(10, 10), metavar="ROWSxCOLS",
                     help="nodes of the sonar patch the soundings are gridded into (default 10x10)")
    run.add_argument("--patch-centre", choices=PATCH_CENTRES, default="vehicle",
                     help="centre of a record's patch when the log has no patch_east_m/patch_north_m: the vehicle "
                          "(default) or the middle of its soundings (a swath gathered in real time, behind the vehicle)")
    navigation_options(run)
    run.set_defaults(handler=_cmd_run)

    demo = commands.add_parser("demo", help="run the built-in scenario into runs/demo")
    navigation_options(demo)
    demo.set_defaults(handler=_cmd_demo, out=None)

    corr = commands.add_parser("correlate", help="correlate a sonar patch against a map file")
    corr.add_argument("map", type=Path, help="map: .npz (write_npz) or any grid read_grid reads")
    corr.add_argument("patch", type=Path, help="patch of depths in metres: .npy, .npz or .csv (empty cell = no beam)")
    corr.add_argument("--backend", choices=sorted(BACKENDS), default="software")
    hardware_options(corr)
    corr.add_argument("--no-mean-compensation", action="store_true", help="plain SAD instead of Nygren's eq. 8.1")
    corr.add_argument("--exclusion-radius", type=int, default=None, help="runner-up exclusion, nodes (default half the patch)")
    corr.add_argument("--lsb-m", type=float, default=None, help="depth word step (default: chosen from the map)")
    corr.add_argument("--json", action="store_true", help="print one JSON object")
    corr.set_defaults(handler=_cmd_correlate)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command == "demo" and args.out is None:
        args.out = Path("runs") / "demo"
    try:
        return args.handler(args)
    except (ValueError, FileNotFoundError) as error:
        print(f"lost {args.command}: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
