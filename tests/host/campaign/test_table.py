"""The campaign's table for a page (summary.md): medians and 90th percentiles per case and estimator, totals of counts."""

from __future__ import annotations

import numpy as np
import pandas as pd

from lost.host.campaign.table import markdown_table


def _rows(case: str, estimator: str, rms: list[float | None], false_fixes: list[int]) -> list[dict]:
    return [{"system": "nav", "case": case, "estimator": estimator, "seed": seed, "rms_m": r, "rms_nodes": None if r is None else r / 10.0,
             "nees_in_band": 0.9, "false_fixes": f, "ms_per_update": 2.0, "error": None} for seed, (r, f) in enumerate(zip(rms, false_fixes))]


def test_a_case_row_gives_median_and_p90_in_the_specs_order_and_sums_the_false_fixes():
    table = pd.DataFrame(_rows("zeta", "pmf", [1.0, 2.0, 3.0, 4.0], [0, 2, 0, 5]) + _rows("alpha", "pmf", [10.0, 20.0, None, 40.0], [0, 0, 0, 0])
                         + [{"system": "nav", "case": "alpha", "estimator": None, "seed": 9, "error": "boom"}])
    text = markdown_table(table, ("zeta", "alpha"))
    lines = text.splitlines()
    assert lines[0].startswith("| case | estimator | runs | RMS m | RMS nodes |") and len(lines) == 4
    zeta, alpha = lines[2], lines[3]  # the spec's order, not the alphabet's; the failed run is no row
    p90 = np.quantile([1.0, 2.0, 3.0, 4.0], 0.9)
    assert zeta.startswith(f"| zeta | pmf | 4 | 2.50 / {p90:#.3g} | 0.250 / {p90 / 10:#.3g} |")
    assert "| 7 |" in zeta  # false fixes summed over the runs, not their median
    # a run that never converged has no RMS: the cell says over how many runs it is
    assert alpha.startswith("| alpha | pmf | 4 | 20.0 / 36.0 (3 of 4) |")
    assert markdown_table(table.iloc[0:0]) == "" and markdown_table(table[table.error.notna()]) == ""


def test_a_trackers_table_takes_its_own_figures():
    table = pd.DataFrame([{"system": "track", "case": "one_diver", "estimator": e, "seed": s, "coverage": 0.9 + 0.01 * s, "false_tracks": 1,
                           "error": None} for e in ("ours", "jpda") for s in range(3)])
    lines = markdown_table(table).splitlines()
    assert "coverage" in lines[0] and "RMS" not in lines[0]
    assert lines[2].startswith("| one_diver | ours | 3 | 0.910 / ") and lines[3].startswith("| one_diver | jpda |")
    assert "| 3 |" in lines[2]  # false tracks summed
