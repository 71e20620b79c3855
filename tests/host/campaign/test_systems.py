"""The tracker and the USBL on the campaign engine: their specs, one run's rows with their own figures, and a tiny
campaign of each on a local cluster with medians and 90th percentiles in summary.json."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from lost.host.campaign import load_campaign, run_campaign, run_task
from lost.host.campaign.spec import RunTask
from lost.host.campaign.systems import FIGURES
from lost.host.config import ConfigError


def _load(tmp_path, text: str):
    path = tmp_path / "campaign.toml"
    path.write_text(text)
    return load_campaign(path)


def test_a_spec_names_its_system_and_the_systems_estimators(tmp_path):
    track = _load(tmp_path, 'system = "track"\nscenarios = ["one_diver"]\nseeds = 2\n')
    assert track.estimators == ("ours",) and all(t.system == "track" and "terrain.seed" not in t.values for t in track.tasks())
    usbl = _load(tmp_path, 'system = "usbl"\nscenarios = ["usbl_turns"]\nseeds = 2\n')
    assert usbl.estimators == ("fused",)
    nav = _load(tmp_path, 'scenarios = ["one_diver"]\nseeds = 2\n')
    assert {t.run_id for t in nav.tasks()}.isdisjoint({t.run_id for t in track.tasks()})  # the system is part of a run's identity
    with pytest.raises(ConfigError, match="'sonar' is not one of"):
        _load(tmp_path, 'system = "sonar"\nscenarios = ["one_diver"]\n')
    with pytest.raises(ConfigError, match=r"\['pmf'\] are not estimators of the track system"):
        _load(tmp_path, 'system = "track"\nscenarios = ["one_diver"]\nestimators = ["pmf"]\n')


def test_a_tracker_run_is_a_row_per_tracker_with_its_figures():
    task = RunTask(case="d", scenario="one_diver", seed=2, values={"duration_s": 20.0, "tracker.particles": 300}, estimators=("ours",),
                   system="track")
    (row,) = run_task(task)
    assert row["error"] is None and row["estimator"] == "ours" and row["pings"] > 10 and row["param.tracker.particles"] == 300
    assert 0.0 <= row["coverage"] <= 1.0 and row["identity_switches"] >= 0 and 0.0 <= row["gospa_mean"] <= 25.0
    assert set(FIGURES["track"]) <= set(row)
    bad = run_task(RunTask(case="d", scenario="one_diver", seed=2, values={"tracker.particles": -1}, estimators=("ours",), system="track"))
    assert bad[0]["estimator"] is None and "particles" in bad[0]["error"]


def test_a_usbl_campaign_runs_on_a_local_cluster_with_its_figures_over_seeds(tmp_path):
    spec = _load(tmp_path, 'name = "u"\nsystem = "usbl"\nscenarios = ["usbl_turns"]\nseeds = 2\n[parameters]\n"duration_s" = [40.0]\n')
    summary = run_campaign(spec, tmp_path / "out", workers=1)
    assert summary["finished"] == 2 and summary["failed_runs"] == 0, summary["errors"]
    table = pd.read_parquet(tmp_path / "out" / "results.parquet")
    assert list(table.seed) == [0, 1] and set(table.system) == {"usbl"} and (table.rms_m < table.usbl_rms_m).all()
    (entry,) = summary["distributions"]
    assert summary["system"] == "usbl" and set(entry) >= set(FIGURES["usbl"]) and entry["estimator"] == "fused"
    assert entry["rms_m"]["median"] == pytest.approx(table.rms_m.median()) and math.isfinite(entry["nees_in_band"]["p90"])
    assert (tmp_path / "out" / "distributions.png").is_file()
