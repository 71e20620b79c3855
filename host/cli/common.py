"""What every subcommand of ``lost`` shares: options, ``--set``, the progress bar, collected warnings, the hardware.

A subcommand module builds its parser from these pieces so that an option means the same everywhere:
``--out``/``--replace`` (an atomic run folder, :mod:`lost.host.runfolder`), ``--set NAME=VALUE`` (one
parser, :func:`setting_argument`, and one merge, :func:`merge_settings`), ``--backend``/``--port``/
``--variant`` (:func:`hardware_options`, :func:`configure_hardware`).
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import sys
import tomllib
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..config import ConfigError
from ..errors import UsageError

if TYPE_CHECKING:
    from ..grid import Grid
    from ..nav.parameters import NavParameters

__all__ = [
    "PROGRESS_ITEMS", "progress_bar", "warnings_collected", "setting_argument", "merge_settings", "positive_metres",
    "output_options", "settings_option", "hardware_options", "configure_hardware",
]

#: Runs longer than this many items (records, pings) show a progress bar.
PROGRESS_ITEMS = 1000


def progress_bar(total: int, description: str, *, minimum: int = PROGRESS_ITEMS) -> Callable[[Iterable], Iterable] | None:
    """A progress bar on stderr over ``total`` items (records, pings, runs), or None for fewer than ``minimum``."""
    if total <= minimum:
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
def warnings_collected() -> Iterator[list[str]]:
    """Yield the list the warnings of the run go to (instead of stderr: the summary shows them)."""
    collector, logger = _Collector(), logging.getLogger("lost.host")
    logger.addHandler(collector)
    try:
        yield collector.messages
    finally:
        logger.removeHandler(collector)


def setting_argument(text: str) -> tuple[str, object]:
    """``NAME=VALUE`` of ``--set``: VALUE as a TOML value (``0.05``, ``true``, ``[0, 200]``, ``"cable"``), ``none`` for
    None, a bare word as a string; the settings' strict schema judges the type after."""
    name, sep, value = text.partition("=")
    if not sep or not name.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    if value.strip().lower() == "none":
        return name.strip(), None
    try:
        return name.strip(), tomllib.loads(f"value = {value}")["value"]
    except tomllib.TOMLDecodeError:
        return name.strip(), value.strip()  # a bare word (cable, software) is a string


def merge_settings(layers: Iterable[tuple[str, Mapping[str, Any]]], known: Iterable[str], what: str,
                   check: Callable[[Mapping[str, Any], str], Any]) -> dict[str, Any]:
    """Merge layers of settings (file tables, then ``--set``, then options), each checked alone first.

    Each layer is validated by ``check(table, where)`` before it is merged, so an error names where its value came
    from; a layer whose name starts with ``--`` is the command line, and its errors are usage errors (exit 2).

    Raises
    ------
    UsageError
        ``--set`` names a field ``known`` does not hold, or a command-line value is refused.
    ConfigError
        A file's value is refused (its path named by ``check``).
    """
    known = set(known)
    merged: dict[str, Any] = {}
    for where, table in layers:
        unknown = sorted(set(table) - known)
        if unknown and where.startswith("--"):
            raise UsageError(f"{where} names no {what}: {', '.join(unknown)} (known: {', '.join(sorted(known))})")
        try:
            check(table, where)
        except ConfigError as error:
            if not where.startswith("--"):
                raise
            # The schema writes a field's path as where.field and a range error as [where]: on the command line the
            # user wrote "--set k=...", so the message says "--set k: ..." and "--set: ...".
            raise UsageError(str(error).replace(f"[{where}]: ", f"{where}: ").replace(f"{where}.", f"{where} ")) from None
        merged.update(table)
    return merged


def positive_metres(text: str) -> float:
    """An option's value as a positive, finite number of metres."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (0 < value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive number of metres, got {text!r}")
    return value


def node_count(text: str) -> int:
    """An option's value as a whole, non-negative number of nodes."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a whole number of nodes, 0 or more, got {text!r}")
    return value


#: ``--backend``'s help, the same for every command that correlates.
BACKEND_HELP = ("correlator backend: software (the fast exact kernel), model (the golden model), rtl (the device co-simulated "
                "on Verilator), fpga (the board, with --port)")


def output_options(sub: argparse.ArgumentParser, default: str) -> None:
    """``--out`` and ``--replace``: the run folder, written whole or not at all."""
    sub.add_argument("--out", type=Path, default=None, help=f"output folder (default {default}), written whole or not at all")
    sub.add_argument("--replace", action="store_true", help="replace an earlier LOST run in --out (whole); without it such a folder is refused")


def settings_option(sub: argparse.ArgumentParser, what: str, example: str) -> None:
    """``--set NAME=VALUE``, repeatable."""
    sub.add_argument("--set", dest="settings", type=setting_argument, action="append", metavar="NAME=VALUE",
                     help=f"{what}; repeatable; VALUE is TOML, or none for None (e.g. {example})")


def hardware_options(sub: argparse.ArgumentParser) -> None:
    """``--port``, ``--baud`` (the board) and ``--variant`` (the co-simulated device)."""
    sub.add_argument("--port", default=None, help="serial port of the board, for --backend fpga (e.g. /dev/ttyUSB0)")
    sub.add_argument("--baud", type=int, default=3_000_000, help="the board's UART rate (default 3000000)")
    from lost.model.variants import DEFAULT_VARIANT, VARIANTS

    sub.add_argument("--variant", default=None, choices=sorted(VARIANTS),
                     help=f"gateware variant of the co-simulated device, for --backend rtl (default {DEFAULT_VARIANT})")


def configure_hardware(args: argparse.Namespace) -> None:
    """``--port`` (and ``--baud``) make the fpga backend; ``--variant`` picks the co-simulated device's."""
    from ..correlator import configure_backend

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
    elif backend == "rtl":
        # Said first, since the command is otherwise silent for minutes while Verilator compiles the device; on stderr,
        # so that --json keeps stdout one JSON object.
        print("--backend rtl: the device's Verilog runs on Verilator; its first build of a variant and size takes minutes "
              "(cached in ~/.cache/lost/cosim), and the simulation runs clock by clock", file=sys.stderr, flush=True)
        if variant:
            configure_backend("rtl", variant=variant)


def map_uncertainty(grid: Grid, params: NavParameters) -> tuple[Grid, dict]:
    """The grid's uncertainty layer made whole for the map error model, and the summary's account of it (``lost run``,
    ``lost serve``)."""
    from ..io.uncertainty import fill_sigma_gaps

    grid, report = fill_sigma_gaps(grid, params.survey_sigma_m)
    report["used"] = params.map_error_m is None and params.map_error_model == "per_node"
    if not report["used"]:
        report["not_used_because"] = ("map_error_m is set" if params.map_error_m is not None else f"map_error_model = {params.map_error_model!r}")
    return grid, {"map_uncertainty": report}
