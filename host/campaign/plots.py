"""The campaign's summary plots: per case and estimator, the distribution over runs of RMS in map nodes,
NEES in band and false fixes (``lost.host.plotting.draw_plots`` draws them; a failure is a warning)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..plotting import pyplot

__all__ = ["campaign_plots"]

_FIGURES = (("rms_nodes", "RMS after convergence (map nodes)"), ("nees_in_band", "NEES in band (share)"), ("false_fixes", "false fixes per run"))


def campaign_plots(table) -> dict[str, Callable[[Path], None]]:
    """``distributions.png``: one panel per figure, a box per case and estimator (nothing without a finished run)."""
    if table.empty or "estimator" not in table or table["estimator"].isna().all():
        return {}
    return {"distributions.png": lambda path: _draw(path, table)}


def _draw(path: Path, table) -> None:
    ok = table[table["error"].isna() & table["estimator"].notna()]
    groups = sorted(ok.groupby(["case", "estimator"]).groups)
    fig, axes = pyplot().subplots(len(_FIGURES), 1, figsize=(max(6.0, 0.9 * len(groups) + 2), 3.2 * len(_FIGURES)), layout="constrained")
    for ax, (column, title) in zip(axes, _FIGURES):
        data = [ok[(ok.case == s) & (ok.estimator == e)][column].dropna().astype(float).to_numpy() for s, e in groups]
        ax.boxplot(data, tick_labels=[f"{s}\n{e}" for s, e in groups], showfliers=True)
        ax.set(title=title)
        ax.grid(True, axis="y", alpha=0.3)
    fig.savefig(path, dpi=100)
