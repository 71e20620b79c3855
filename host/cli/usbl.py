"""``lost usbl``: INS+USBL positioning of a recorded or simulated tow.

::

    lost usbl LOG.csv --svp CAST.csv [--imu IMU.csv] [--config USBL.toml] [--out DIR]
    lost usbl SCENARIO.toml [--out DIR]        (or a shipped scenario's name: lost usbl usbl_turns)
    lost usbl --list                           the shipped scenarios

writes ``track.csv``, ``summary.json``, ``track.png``, ``error.png`` (with truth) and ``profile.png`` into
``--out``; a scenario run also writes the simulated recording it processed (``inputs/log.csv``, ``imu.csv``,
``cast.csv``) in the layouts a recorded tow uses, and the settings it processed them with (``inputs/usbl.toml``, a
``--config`` file): ``lost usbl DIR/inputs/log.csv --svp DIR/inputs/cast.csv --config DIR/inputs/usbl.toml`` repeats it.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

from ..errors import UsageError
from ..runfolder import run_folder
from ..usbl.pipeline import UsblConfig, process, read_imu, read_log
from ..usbl.report import summarize, write_outputs
from ..usbl.scenario import builtin_usbl_scenarios, load_processing_config, load_usbl_scenario, processing_config_toml
from ..usbl.simulate import simulate_tow
from ..usbl.sound import read_cast
from .common import output_options, warnings_collected

__all__ = ["register", "run_usbl"]


def register(commands, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``lost usbl``."""
    usbl = commands.add_parser("usbl", parents=parents, help="INS+USBL positioning of a recorded log or a simulated scenario")
    usbl.add_argument("source", nargs="?", help="USBL log CSV, or a scenario TOML file, or a shipped scenario's name (lost usbl --list)")
    usbl.add_argument("--list", action="store_true", help="list the shipped scenarios with their descriptions, and stop")
    usbl.add_argument("--svp", type=Path, help="CTD or SVP cast CSV (required with a log)")
    usbl.add_argument("--imu", type=Path, help="IMU CSV (default: imu.csv beside the log)")
    usbl.add_argument("--config", type=Path, help="processing settings TOML: [usbl], [imu], gate_probability, align_window_s, earth_rotation")
    output_options(usbl, "runs/usbl-NAME")
    usbl.set_defaults(handler=run_usbl)


def _is_log(source: str) -> bool:
    return source.lower().endswith(".csv")


def run_usbl(args: argparse.Namespace) -> int:
    """The handler of ``lost usbl``."""
    if args.list:
        for name in builtin_usbl_scenarios():
            print(f"{name:<18} {load_usbl_scenario(name).description}")
        return 0
    if args.source is None:
        raise UsageError("give a log (LOG.csv --svp CAST.csv) or a scenario (a TOML file, or a shipped one's name: lost usbl --list)")
    start = time.perf_counter()
    if _is_log(args.source):
        if args.svp is None:
            raise UsageError("a log needs its sound-speed cast: --svp CAST.csv")
        config = UsblConfig(**load_processing_config(args.config)) if args.config else UsblConfig()
        name, scenario = Path(args.source).stem, None
    else:
        if args.svp or args.imu or args.config:
            raise UsageError("--svp, --imu and --config are for a recorded log; a scenario names its own cast and settings")
        scenario = load_usbl_scenario(args.source)
        name = scenario.name
        config = scenario.processing_config()  # the scenario's array, IMU, gate and [processing] table
    out = args.out = args.out or Path("runs") / f"usbl-{name}"
    with run_folder(out, replace=args.replace, command="usbl") as folder, warnings_collected() as warnings:
        log_path, imu_path, cast_path = _inputs(args, scenario, config, folder)
        if scenario is None and args.config is None:
            warnings.append("no --config: the USBL array (frequency, baseline, noise, lever arms, turnaround) and the IMU's errors "
                            "are lost.host.usbl's defaults, not read from a file (docs/usbl.md, 'The config TOML')")
        log = read_log(log_path, turnaround_s=config.array.turnaround_s)
        imu = read_imu(imu_path)
        cast = read_cast(cast_path, default_position=(float(log["ship_lat_deg"].iloc[0]), float(log["ship_lon_deg"].iloc[0])))
        if cast_path.is_relative_to(folder):  # name the cast where the finished run keeps it, not in the folder being written
            cast = replace(cast, source=str(out / cast_path.relative_to(folder)))
        run = process(log, imu, cast, config)
        summary = summarize(run, name=name, run_time_s=time.perf_counter() - start)
        write_outputs(folder, run, summary, warnings)
    _print(summary, out)
    return 0


def _inputs(args: argparse.Namespace, scenario, config: UsblConfig, folder: Path) -> tuple[Path, Path, Path]:
    """The log, IMU and cast files: the recorded ones, or a scenario's simulated recording written into ``folder/inputs``
    with the settings ``config`` that process it (``usbl.toml``)."""
    if scenario is None:
        log_path = Path(args.source)
        return log_path, args.imu or log_path.with_name("imu.csv"), args.svp
    inputs = folder / "inputs"
    inputs.mkdir()
    sim = simulate_tow(scenario)
    sim.log.to_csv(inputs / "log.csv", index=False, float_format="%.12g")
    sim.imu.to_csv(inputs / "imu.csv", index=False, float_format="%.12g")
    (inputs / "cast.csv").write_text(Path(sim.cast.source).read_text())
    (inputs / "usbl.toml").write_text(f"# The settings lost usbl {args.source} processed inputs/log.csv with (its --config).\n"
                                      + processing_config_toml(config))
    return inputs / "log.csv", inputs / "imu.csv", inputs / "cast.csv"


def _print(summary: dict, out: Path) -> None:
    gating = summary["gating"]
    print(f"{summary['name']}: {summary['pings']} pings over {summary['duration_s']:.0f} s, processed in {summary['run_time_s']:.1f} s; "
          f"fixes accepted {gating['accepted']}, rejected {gating['rejected']}, failed {gating['failed']}, dropouts {gating['dropout']}")
    if summary["truth_known"]:
        print(f"{'method':16s} {'rms_m':>9s} {'p95_m':>9s} {'max_m':>9s}")
        for method, stats in summary["methods"].items():
            cells = ["-" if stats[k] is None else f"{stats[k]:.2f}" for k in ("rms_m", "p95_m", "max_m")]
            print(f"{method:16s} {cells[0]:>9s} {cells[1]:>9s} {cells[2]:>9s}")
        if "injected_bad" in gating:
            caught = gating["injected_bad_caught_fraction"]
            print(f"bad fixes caught {caught:.1%} of {gating['injected_bad']}; good fixes rejected {gating['good_rejected_fraction']:.2%} of {gating['good']}")
        nees = summary["nees"]
        print(f"NEES (3 dof) inside its 95 % band at {nees['fraction_inside']:.1%} of epochs (mean {nees['mean']:.2f})")
        if "goals" in summary:
            print("goals: " + ", ".join(f"{name} {'met' if met else 'NOT met'}" for name, met in summary["goals"].items()))
    drawn = [name for name in ("track.png", "error.png", "profile.png") if (out / name).is_file()]
    print(f"wrote {out}/" + ", ".join(["track.csv", "summary.json", *drawn]))
    for warning in summary.get("warnings", ()):
        print(f"warning: {warning}")

