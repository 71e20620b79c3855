"""``lost survey`` and ``lost grid`` on real files: what they print, what they write, how they refuse."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from lost.host.cli import main
from lost.host.io import read_grid
from lost.host.io.survey_summary import summarize_survey

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
GSF = REAL / "noaa_okeanos_ex1604_gsf" / "0029_20160323_185603_EX1604_MB.gsf"
needs_real = pytest.mark.skipif(not REAL.is_dir(), reason=f"the real survey files are not at {REAL} (shared/data/real_survey beside the repository)")


@needs_real
def test_survey_json_is_the_summary(capsys):
    assert main(["survey", "--json", str(GSF)]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed == json.loads(json.dumps(summarize_survey(GSF)))
    assert printed["pings"] == 8 and printed["valid_soundings"] == 2369


@needs_real
def test_survey_text_names_the_counts(capsys):
    assert main(["survey", str(GSF)]) == 0
    assert "pings 8, beams per ping 432, valid soundings 2369 of 3456" in capsys.readouterr().out


@needs_real
def test_grid_writes_a_netcdf_read_grid_reads_and_refuses_to_overwrite_it(tmp_path, capsys):
    out = tmp_path / "ex1604.nc"
    assert main(["grid", str(GSF), "--node-m", "100", "--out", str(out)]) == 0
    assert "nodes of 100 m in EPSG:32658" in capsys.readouterr().out
    grid = read_grid(out)
    assert grid.node_m == 100.0 and np.isfinite(grid.depth_m).sum() > 0
    assert main(["grid", str(GSF), "--node-m", "100", "--out", str(out)]) == 2
    assert "exists; pass --replace" in capsys.readouterr().err
    assert main(["grid", str(GSF), "--node-m", "50", "--out", str(out), "--replace"]) == 0
    assert read_grid(out).node_m == 50.0


def test_grid_refuses_a_node_spacing_that_is_no_length(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["grid", "x.all", "--node-m", "-5", "--out", str(tmp_path / "g.nc")])
    assert stop.value.code == 2 and "expected a positive number of metres" in capsys.readouterr().err


def test_survey_of_a_file_that_is_no_survey_is_one_line_naming_it(tmp_path, capsys):
    path = tmp_path / "notes.gsf"
    path.write_text("not a sonar file at all\n")
    assert main(["survey", str(path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "lost survey: notes.gsf is not a Kongsberg .all, .kmall or GSF file" in err
    assert not list(tmp_path.glob("*.nc*"))


@needs_real
def test_lost_correlate_takes_a_lost_grid_whose_layer_has_gaps(tmp_path, capsys):
    out = tmp_path / "ex1604.nc"
    assert main(["grid", str(GSF), "--node-m", "100", "--out", str(out)]) == 0
    grid = read_grid(out)
    assert np.any(np.isfinite(grid.depth_m) & np.isnan(grid.sigma_m))  # nodes of one sounding: no spread
    patch = tmp_path / "p.csv"
    np.savetxt(patch, np.full((2, 2), float(np.nanmedian(grid.depth_m))), delimiter=",")
    capsys.readouterr()
    assert main(["correlate", str(out), str(patch)]) == 0
    assert "best fit" in capsys.readouterr().out
