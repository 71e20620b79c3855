"""Run reports: statistics, the convergence rule, the track CSV and summary.json."""

import csv
import json

import numpy as np
import pytest

from lost.host.nav.pipeline import FilterTrack, NavResult
from lost.host.report import ConvergenceRule, convergence_index, error_stats, filter_figures, summarize, write_summary, write_track_csv


def test_error_stats_by_hand():
    stats = error_stats(np.array([3.0, 4.0, np.nan, 0.0]))
    assert stats["rms_m"] == pytest.approx(np.sqrt(25.0 / 3.0), abs=1e-3)
    assert stats["max_m"] == 4.0 and stats["records"] == 3
    assert error_stats(np.array([np.nan]))["rms_m"] is None


def test_convergence_needs_an_unbroken_hold():
    t = np.arange(10.0)
    errors = np.array([200, 50, 10, 10, 30, 5, 5, 5, 5, 40], float)
    assert convergence_index(t, errors, ConvergenceRule(radius_m=20.0, hold_s=3.0)) == 5
    assert convergence_index(t, errors, ConvergenceRule(radius_m=20.0, hold_s=4.0)) is None
    assert convergence_index(t, errors, ConvergenceRule(radius_m=35.0, hold_s=4.0)) == 2


def _result(n=6):
    truth = np.column_stack([np.arange(n) * 10.0, np.zeros(n)])
    estimate = truth + np.array([[100.0, 0.0]] + [[3.0, 4.0]] * (n - 1))
    nan2 = np.full((n, 2), np.nan)
    return NavResult(
        t_s=np.arange(n, dtype=float), estimate=estimate, predicted=estimate, mle=nan2, mle_source=np.array([""] * n),
        distinctness=np.full(n, np.nan), cat=nan2, cross_velocity_mps=np.full(n, np.nan),
        slant_corrected=np.zeros(n, bool), off_map=np.array([False] * (n - 1) + [True]),
        layback=truth + (0.0, 50.0), dead_reckoning=truth + (0.0, 100.0), truth=truth, counts={"records": n},
    )


def test_summary_and_files(tmp_path):
    result = _result()
    summary = summarize(result, name="hand", parameters={"k": 100.0}, rule=ConvergenceRule(radius_m=10.0, hold_s=2.0))
    assert summary["convergence"]["time_s"] == 1.0 and summary["convergence"]["initial_error_m"] == 100.0
    assert summary["methods"]["lost"]["rms_m"] == 5.0 and summary["methods"]["lost"]["whole_run"]["max_m"] == 100.0
    assert summary["methods"]["layback"]["p95_m"] == 50.0 and summary["methods"]["dead_reckoning"]["max_m"] == 100.0
    assert summary["off_map_records"] == 1
    write_summary(tmp_path / "summary.json", summary)
    assert json.loads((tmp_path / "summary.json").read_text()) == summary
    write_track_csv(tmp_path / "track.csv", result)
    with open(tmp_path / "track.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == 6
    assert [r["stage"] for r in rows] == ["initialization"] + ["dead_reckoning"] * 4 + ["off_map"]
    assert float(rows[2]["error_m"]) == 5.0 and rows[2]["mle_x_m"] == "" and float(rows[2]["layback_error_m"]) == 50.0


def test_the_track_csv_carries_each_filters_hold_and_reinitialization_cause(tmp_path):
    track = FilterTrack.empty(6)
    track.held[2:4] = True
    track.reinitialized[4] = "lookalike"
    result = NavResult(**{**_result().__dict__, "tracks": {"pmf": track}})
    write_track_csv(tmp_path / "track.csv", result)
    with open(tmp_path / "track.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert [r["pmf_held"] for r in rows] == ["0", "0", "1", "1", "0", "0"]
    assert [r["pmf_reinitialized"] for r in rows] == ["", "", "", "", "lookalike", ""]


def test_summary_without_truth_has_no_errors():
    result = _result()
    result = NavResult(**{**result.__dict__, "truth": None})
    summary = summarize(result, name="log", parameters={})
    assert summary["truth_known"] is False and summary["methods"] == {}


def test_a_filters_figures_carry_its_last_depth_bias_estimate_or_none():
    track = FilterTrack.empty(4)
    assert filter_figures(track, None, None)["depth_bias_m"] is None  # the patch form
    track.depth_bias_m[:3] = [0.5, 1.25, 1.5]
    assert filter_figures(track, None, None)["depth_bias_m"] == 1.5  # the last finite estimate


def test_a_filters_figures_carry_its_last_velocity_bias_estimate_with_its_sigma_or_none():
    track = FilterTrack.empty(4)
    assert filter_figures(track, None, None)["velocity_bias_mps"] is None  # an estimator without one
    track.velocity_bias_mps[:3] = [[0.01, -0.02], [0.02, -0.015], [0.021, np.nan]]
    track.velocity_bias_sigma_mps[:3] = [[0.05, 0.05], [0.0072, 0.0076], [0.007, np.nan]]
    figures = filter_figures(track, None, None)
    assert figures["velocity_bias_mps"] == [0.02, -0.015]  # the last row with both axes
    assert figures["velocity_bias_sigma_mps"] == [0.0072, 0.0076]


def test_a_filters_usable_rms_counts_the_records_it_flagged_usable_after_its_convergence():
    result = _result(8)
    track = FilterTrack.empty(8)
    track.position[:] = result.truth + np.array([[100.0, 0.0], [3.0, 4.0], [3.0, 4.0], [3.0, 4.0], [30.0, 40.0], [30.0, 40.0], [0.0, 1.0],
                                                  [0.0, 1.0]])
    track.usable[:] = [False, True, True, True, False, False, True, True]
    summary = summarize(NavResult(**{**result.__dict__, "tracks": {"pmf": track}}), name="hand", parameters={},
                        rule=ConvergenceRule(radius_m=10.0, hold_s=2.0))
    pmf = summary["methods"]["pmf"]
    assert pmf["convergence_time_s"] == 1.0 and pmf["rms_m"] == pytest.approx(np.sqrt((3 * 25 + 2 * 2500 + 2) / 7), abs=1e-3)
    # the two records 50 m off were flagged not usable: the usable RMS leaves them out
    assert pmf["usable_records"] == 5 and pmf["usable_rms_m"] == pytest.approx(np.sqrt((3 * 25 + 2) / 5), abs=1e-3)
    never = FilterTrack.empty(8)
    never.position[:] = result.truth + 100.0
    summary = summarize(NavResult(**{**result.__dict__, "tracks": {"pmf": never}}), name="hand", parameters={})
    assert summary["methods"]["pmf"]["usable_rms_m"] is None and summary["methods"]["pmf"]["usable_records"] == 0
