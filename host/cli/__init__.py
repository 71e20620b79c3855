"""The ``lost`` command: one module per subcommand, registered by name in :data:`COMMANDS`.

::

    lost run SCENARIO.toml [--out DIR]                  a simulated tow (a file, or a built-in name)
    lost run --log nav.csv --bathy grid.nc [--sonar soundings.csv] [--svp CAST.csv] [--out DIR]
    lost demo [--out runs/demo]                         the built-in scenario "demo"
    lost correlate MAP PATCH                            best fit and runner-up of a patch on a map
    lost survey FILE... [--json]                        what is inside Kongsberg .all/.kmall and GSF files
    lost grid FILE... --node-m M --out GRID.nc          a bathymetry grid (mean, count, std) from their soundings
    lost track DETECTIONS.csv|SCENARIO [--out DIR]      sonar contact tracking
    lost usbl LOG.csv --svp CAST.csv | SCENARIO         INS+USBL positioning of the towfish
    lost campaign SPEC.toml [--out DIR]                 many simulated tows on Dask, a table of results
    lost plan MAP [--route WAYPOINTS.csv]               where terrain navigation will work, and how well
    lost replay SOURCE --to HOST:PORT [--speed X]       a survey or scenario sent as live .kmall and NMEA datagrams (UDP)

Every command that writes files writes them into a run folder (``--out``), whole or not at all
(:mod:`lost.host.runfolder`): an earlier LOST run there is replaced only with ``--replace``.

A subcommand is a module of this package with ``register(commands, parents)``, which adds its parser to
``commands`` (argparse's subparsers, with ``parents`` for the shared ``--debug``) and sets its handler
(``handler(args) -> int``); adding one is a new module and its name in :data:`COMMANDS`. The shared options
and helpers are in :mod:`lost.host.cli.common`.

Exit codes: 0 done; 1 an error in the inputs or the outputs (one line on stderr naming the file or
field; ``--debug`` adds the traceback); 2 a usage error (options); 130 interrupted (Ctrl-C or
SIGTERM), the output folder left as it was.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import signal
import sys
import traceback
from pathlib import Path

from ..errors import UsageError
from ..runfolder import describe_untouched
from .common import PROGRESS_ITEMS, progress_bar, setting_argument

__all__ = ["main", "build_parser", "COMMANDS", "UsageError", "EXIT_OK", "EXIT_ERROR", "EXIT_USAGE", "EXIT_INTERRUPTED",
           "PROGRESS_ITEMS", "progress_bar", "setting_argument"]

EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130

#: The subcommands, in the order ``lost --help`` lists them: each is the module of this package of that name.
COMMANDS = ("run", "demo", "correlate", "survey", "grid", "track", "usbl", "campaign", "plan", "replay")


def build_parser() -> argparse.ArgumentParser:
    """The parser of ``lost`` with every subcommand of :data:`COMMANDS` registered."""
    parser = argparse.ArgumentParser(prog="lost", description="LOST: terrain navigation for underwater towed vehicles")
    # SUPPRESS on both levels, so `lost --debug run` and `lost run --debug` both work (a subparser's
    # default would otherwise overwrite the top level's value).
    debug = argparse.ArgumentParser(add_help=False)
    debug.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show the traceback of an error")
    parser.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show the traceback of an error")
    commands = parser.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        importlib.import_module(f".{name}", __name__).register(commands, [debug])
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
    try:
        with _sigterm_interrupts():
            return args.handler(args)
    except (Exception, KeyboardInterrupt) as error:
        if getattr(args, "debug", False):
            traceback.print_exc(file=sys.stderr)
        message = "interrupted" if isinstance(error, KeyboardInterrupt) else _one_line(error)
        out = getattr(args, "out", None)
        if out is not None and not isinstance(error, UsageError):
            message += f"; {describe_untouched(Path(out))}"
        print(f"lost {args.command}: {message}", file=sys.stderr)
        return _exit_code(error)
