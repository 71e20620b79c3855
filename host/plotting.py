"""Plots of a run, drawn so that a plot that fails costs only itself: a warning in the summary, never the results.

Every subcommand hands its plots to :func:`draw_plots` as named drawing functions after its results (tracks,
tables) are written and before its summary is; a plot that raises is recorded as a warning naming the file and
the error, and the run goes on. Matplotlib draws to files only (the Agg backend, no display).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

__all__ = ["draw_plots", "pyplot", "map_figure_size"]

def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (files only, no display)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def draw_plots(out: Path, plots: Mapping[str, Callable[[Path], object]], warnings: list[str]) -> list[Path]:
    """Draw each plot into ``out / name``; return the files written. A plot that fails is a warning in ``warnings``.

    A drawing function takes the path to write. Whatever it leaves open is closed, so a failed plot leaks no figure.
    """
    plt = pyplot()
    written = []
    for name, draw in plots.items():
        path = out / name
        try:
            draw(path)
        except Exception as error:  # a plot never costs a result: any failure of drawing is reported, not raised
            path.unlink(missing_ok=True)
            message = f"{name} was not drawn: {type(error).__name__}: {' '.join(str(error).split())}"
            warnings.append(message)
        else:
            written.append(path)
        finally:
            plt.close("all")
    return written


def map_figure_size(width_m: float, height_m: float, *, longest_in: float = 10.0, side_in: float = 1.8,
                    margin_in: float = 1.0) -> tuple[float, float]:
    """A figure size that gives a map of ``width_m`` x ``height_m`` (drawn at equal aspect) the canvas's long side.

    ``side_in`` is the room of a colour bar and labels beside the map, ``margin_in`` that of the title and the axis
    labels above and below; the map itself gets ``longest_in`` along its longer side, so a tall map fills the height
    and a wide one the width, and no side shrinks below a third of the longest.
    """
    aspect = min(max(height_m / width_m, 1 / 3), 3.0) if width_m > 0 and height_m > 0 else 1.0
    map_w, map_h = (longest_in, longest_in * aspect) if aspect <= 1 else (longest_in / aspect, longest_in)
    return map_w + side_in, map_h + margin_in
