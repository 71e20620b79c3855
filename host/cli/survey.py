"""``lost survey FILE... [--json]``: what is inside multibeam files (format, pings, beams, valid soundings, time, extent, depths, skips)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

__all__ = ["register"]


def _cmd_survey(args: argparse.Namespace) -> int:
    from ..io.survey_summary import format_summary, summarize_survey

    summary = summarize_survey(args.files, crs=args.crs)
    print(json.dumps(summary, indent=2) if args.json else format_summary(summary))
    return 0


def register(commands, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``lost survey``."""
    survey = commands.add_parser("survey", parents=parents, help="what is inside Kongsberg .all/.kmall or GSF files")
    survey.add_argument("files", type=Path, nargs="+", help="survey files of one format, in time order")
    survey.add_argument("--crs", default=None, help="projected CRS of the pings (default: the UTM zone of the first ping)")
    survey.add_argument("--json", action="store_true", help="print one JSON object")
    survey.set_defaults(handler=_cmd_survey)
