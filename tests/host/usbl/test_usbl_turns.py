"""The issue's goals on the shipped scenario `usbl_turns`, through `lost usbl usbl_turns` (about 10 s)."""

import json

import numpy as np
import pandas as pd
import pytest

from lost.host.cli import main


@pytest.fixture(scope="module")
def turns(tmp_path_factory):
    out = tmp_path_factory.mktemp("usbl_turns")
    assert main(["usbl", "usbl_turns", "--out", str(out)]) == 0
    return json.loads((out / "summary.json").read_text()), pd.read_csv(out / "track.csv"), out


def test_a_fused_position_at_every_epoch(turns):
    summary, track, _ = turns
    assert summary["epochs_without_fused_position"] == 0
    assert summary["epochs_before_start"] == 1  # the first fix's ping aligns the INS; the fused track starts with the next ping
    assert len(track) == summary["pings"] - 1
    assert np.all(np.isfinite(track[["north_m", "east_m", "depth_m", "var_north_m2", "var_east_m2", "var_depth_m2"]].to_numpy()))
    assert summary["gating"]["dropout"] > 50  # the turns' dropouts were bridged, not skipped


def test_fused_rms_is_at_most_half_the_raw_usbl(turns):
    methods = turns[0]["methods"]
    assert methods["fused"]["rms_m"] <= 0.5 * methods["usbl"]["rms_m"]
    assert methods["fused"]["rms_m"] <= 0.5 * methods["usbl_good_fixes"]["rms_m"]  # also against the good fixes alone


def test_gating_catches_bad_fixes_and_keeps_good_ones(turns):
    gating = turns[0]["gating"]
    assert gating["injected_bad"] > 50
    assert gating["injected_bad_caught_fraction"] >= 0.95
    assert gating["good_rejected_fraction"] <= 0.01


def test_nees_inside_its_band_at_nine_epochs_in_ten(turns):
    nees = turns[0]["nees"]
    assert nees["fraction_inside"] >= 0.90
    assert 2.0 < nees["mean"] < 4.5


def test_outputs_are_written(turns):
    _, track, out = turns
    for name in ("track.png", "error.png", "profile.png", "inputs/log.csv", "inputs/imu.csv", "inputs/cast.csv", "inputs/usbl.toml"):
        assert (out / name).stat().st_size > 0
    assert set(track.status) <= {"alignment", "accepted", "rejected", "failed", "dropout"}
    assert track.lat_deg.between(17.9, 18.1).all() and track.utm_northing_m.between(1.9e6, 2.1e6).all()


def test_the_summary_states_each_goal(turns):
    goals = turns[0]["goals"]
    assert len(goals) == 5 and all(goals.values())


def test_the_summary_names_the_cast_where_the_run_keeps_it(turns):
    summary, _, out = turns
    assert summary["cast"]["source"] == str(out / "inputs" / "cast.csv")
    assert (out / "inputs" / "cast.csv").is_file()
