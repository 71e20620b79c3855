"""The campaign's summary plots: per case and estimator, the distribution over runs of the system's main figures (the
navigation's RMS in map nodes, NEES in band and false fixes; :data:`lost.host.campaign.systems.PLOTTED`), drawn by
``lost.host.plotting.draw_plots`` (a failure is a warning)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..plotting import pyplot

__all__ = ["campaign_plots"]



def campaign_plots(table) -> dict[str, Callable[[Path], None]]:
    """``distributions.png``: one panel per figure, a box per case and estimator (nothing without a finished run)."""
    if table.empty or "estimator" not in table or table["estimator"].isna().all():
        return {}
    return {"distributions.png": lambda path: _draw(path, table)}


def _draw(path: Path, table) -> None:
    from .systems import PLOTTED, system_of

    figures = PLOTTED[system_of(table)]
    ok = table[table["error"].isna() & table["estimator"].notna()]
    groups = sorted(ok.groupby(["case", "estimator"]).groups)
    fig, axes = pyplot().subplots(len(figures), 1, figsize=(max(6.0, 0.9 * len(groups) + 2), 3.2 * len(figures)), layout="constrained")
    for ax, (column, title) in zip(axes, figures):
        data = [ok[(ok.case == s) & (ok.estimator == e)][column].dropna().astype(float).to_numpy() if column in ok else [] for s, e in groups]
        ax.boxplot(data, tick_labels=[f"{s}\n{e}" for s, e in groups], showfliers=True)
        ax.set(title=title)
        ax.grid(True, axis="y", alpha=0.3)
    fig.savefig(path, dpi=100)
