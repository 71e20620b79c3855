"""The campaign's table for a page (``summary.md``): per case and estimator, the median / 90th percentile over the runs
of the system's main figures, and the total over the runs where a count adds up (false fixes, false tracks).

The same numbers as ``summary.json``'s distributions, in the cases' order of the spec; a case whose figure some runs
lack (the navigation's RMS after convergence where a run never converged) says over how many runs it is.
"""

from __future__ import annotations

from typing import Any

__all__ = ["TABLED", "markdown_table"]

#: Per system: each column's figure, its heading, and ``spread`` (median / 90th percentile) or ``total`` (the sum).
TABLED = {
    "nav": (("rms_m", "RMS m", "spread"), ("rms_nodes", "RMS nodes", "spread"), ("usable_rms_nodes", "while usable, nodes", "spread"),
            ("nees_in_band", "NEES in band", "spread"), ("false_fixes", "false fixes", "total"),
            ("convergence_time_s", "convergence s", "spread"), ("ms_per_update", "ms/update", "spread")),
    "track": (("coverage", "coverage", "spread"), ("first_lock", "first lock", "spread"), ("identity_switches", "identity switches", "total"),
              ("false_tracks", "false tracks", "total"), ("gospa_mean", "GOSPA mean", "spread"), ("ms_per_ping", "ms/ping", "spread")),
    "usbl": (("rms_m", "RMS m", "spread"), ("usbl_rms_m", "USBL alone RMS m", "spread"), ("nees_in_band", "NEES in band", "spread"),
             ("good_rejected", "good rejected", "spread"), ("bad_caught", "bad caught", "spread")),
}


def markdown_table(table: Any, cases: tuple[str, ...] = ()) -> str:
    """The table of a campaign's rows (``results.parquet``'s frame): one line per case and estimator, ``cases`` first in
    their order (any other case after them, sorted); empty without a finished row."""
    from .systems import system_of

    if table.empty or "estimator" not in table:
        return ""
    ok = table[table["error"].isna() & table["estimator"].notna()] if "error" in table else table[table["estimator"].notna()]
    if ok.empty:
        return ""
    columns = TABLED[system_of(table)]
    present = list(dict.fromkeys(ok["case"]))
    order = [case for case in cases if case in present] + sorted(case for case in present if case not in cases)
    lines = ["| case | estimator | runs | " + " | ".join(title for _, title, _ in columns) + " |",
             "|---|---|---|" + "---|" * len(columns)]
    for case in order:
        rows = ok[ok["case"] == case]
        for estimator in dict.fromkeys(rows["estimator"]):
            group = rows[rows["estimator"] == estimator]
            cells = [_cell(group, figure, kind) for figure, _, kind in columns]
            lines.append(f"| {case} | {estimator} | {len(group)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _cell(group: Any, figure: str, kind: str) -> str:
    """One figure over a group's runs: ``median / p90`` (over how many runs, where some lack it) or the total."""
    if figure not in group:
        return "-"
    values = group[figure].dropna().astype(float)
    if values.empty:
        return "-"
    if kind == "total":
        return f"{values.sum():g}"
    text = f"{_number(values.median())} / {_number(values.quantile(0.9))}"
    return text if len(values) == len(group) else f"{text} ({len(values)} of {len(group)})"


def _number(value: float) -> str:
    """Three significant figures (trailing zeros kept), whole numbers from 100 on."""
    return f"{value:#.3g}" if abs(value) < 100 else f"{value:.0f}"
