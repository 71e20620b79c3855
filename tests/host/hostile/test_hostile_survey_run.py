"""`lost run --survey` on bad input: a survey off its map, files of different ships, intervals without a valid beam, bad options."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from lost.host.cli import main
from lost.host.grid import Grid
from lost.host.io import write_npz
from lost.host.io.errors import DifferentShipsError
from lost.host.io.survey import open_survey
from lost.host.io.survey_records import SurveyRecorder

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
EM122 = REAL / "ga4430_em122_all" / "0243_P007_MBES_EM122_20150207_044356_Supporter_GA4430.all"
EM710 = REAL / "ausseabed_investigator_em710_all" / "0000_20200107_035504_Investigator_em710.all"
needs_real = pytest.mark.skipif(not EM122.is_file(), reason=f"the real survey files are not at {REAL} (shared/data/real_survey beside the repository)")


def _far_map(tmp_path) -> Path:
    """A map in the EM122 file's UTM zone, 100 km from where it sailed."""
    return write_npz(Grid(np.full((50, 50), 3500.0), 374_000.0, 5_689_000.0, 20.0, "EPSG:32745"), tmp_path / "far.npz")


@needs_real
def test_a_survey_outside_its_map_is_refused_and_nothing_is_written(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["run", "--survey", str(EM122), "--bathy", str(_far_map(tmp_path)), "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "no position of the survey's track lies on the map" in err and "EPSG:32745" in err and err.count("\n") == 1
    assert not out.exists()


@needs_real
def test_files_of_different_ships_are_refused_naming_them(tmp_path, capsys):
    with pytest.raises(DifferentShipsError, match="a ping of sonar head or ship 229 .* after records of \\[117\\] only"):
        recorder = SurveyRecorder(node_m=20.0, patch_shape=(4, 4), interval_s=5.0)
        for ping in open_survey([EM122, EM710], crs="EPSG:32745"):
            recorder.add(ping)
    assert main(["run", "--survey", str(EM122), str(EM710), "--bathy", str(_far_map(tmp_path)), "--out", str(tmp_path / "r")]) == 1
    assert "files of different ships (or sonars) cannot make one survey's records" in capsys.readouterr().err


@needs_real
def test_a_record_interval_with_no_valid_beam_is_kept_without_a_patch_and_counted():
    pings = list(open_survey(EM122))
    flagged = [replace(p, valid=np.zeros_like(p.valid)) if 7.0 <= p.time_s - pings[0].time_s < 16.0 else p for p in pings]
    recorder = SurveyRecorder(node_m=20.0, patch_shape=(4, 4), interval_s=3.0)
    records = [r for p in flagged for r in recorder.add(p)] + recorder.finish()
    assert len(records) == 6
    without = [r for r in records if r.sonar is None]
    assert [round(r.t_s, 1) for r in without] == [7.9, 15.6] and all(r.soundings == 0 for r in without)
    assert recorder.skipped["record interval with no valid beam (kept without a patch)"] == 2
    assert all(np.isfinite(r.ship_x_m) for r in records)  # the navigation dead-reckons through them


@pytest.mark.parametrize(("argv", "message"), [
    (["--survey", "a.all", "--bathy", "g.nc", "--dr-bias", "0.1"], "expected two numbers E,N"),
    (["--survey", "a.all", "--bathy", "g.nc", "--start-offset", "nan,3"], "expected two finite numbers E,N"),
    (["--survey", "a.all", "--bathy", "g.nc", "--record-s", "0"], "expected a positive number of seconds"),
])
def test_bad_survey_option_values_exit_2(argv, message, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["run", *argv])
    assert stop.value.code == 2 and message in capsys.readouterr().err


@pytest.mark.parametrize(("argv", "message"), [
    (["--survey", "a.all"], "lost run --survey needs the map: --bathy"),
    (["--survey", "a.all", "--log", "nav.csv", "--bathy", "g.nc"], "give one of a scenario, --log or --survey"),
    (["--survey", "a.all", "--bathy", "g.nc", "--sonar", "s.csv"], "--sonar and --svp belong to a navigation log"),
    (["--log", "nav.csv", "--bathy", "g.nc", "--dr-bias", "0.1,0"], "--dr-bias apply to a recorded survey"),
    (["short", "--start-offset", "1,2"], "--start-offset apply to a recorded survey"),
])
def test_survey_options_out_of_place_exit_2(argv, message, capsys, tmp_path):
    assert main(["run", *argv, "--out", str(tmp_path / "r")]) == 2
    assert message in capsys.readouterr().err
