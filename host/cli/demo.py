"""``lost demo``: the built-in scenario ``demo`` through the whole navigation into ``runs/demo`` (see :mod:`.run`)."""

from __future__ import annotations

import argparse

from .run import navigation_options, run_demo

__all__ = ["register"]


def register(commands, parents: list[argparse.ArgumentParser]) -> None:
    """Add ``lost demo``."""
    demo = commands.add_parser("demo", parents=parents, help="run the built-in scenario into runs/demo")
    navigation_options(demo, "runs/demo, replaced at each run")
    demo.set_defaults(handler=run_demo, no_plots=False)  # the demo draws its figures
