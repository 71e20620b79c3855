"""Hostile USBL fix files for `lost run --survey --usbl-fixes`: a file without a fix, a missing file, the option without a
survey, vendor sentences that nothing can date: each a named error or a counted skip, and no run folder written."""

from __future__ import annotations

import json
from itertools import islice

import pytest

from lost.host.cli import main
from lost.host.io import write_npz
from lost.host.io.kmall_write import write_kmall_pings
from lost.host.io.simulated import EPOCH_S, simulated_pings
from lost.host.live.inputs import UsblFix, json_input_line
from lost.host.live.usbl import read_usbl_fixes
from lost.host.live.usbl_nmea import psonlld_sentence
from lost.host.scenario import builtin_scenario_path, load_scenario


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    folder = tmp_path_factory.mktemp("survey")
    grid, _, pings = simulated_pings(load_scenario(builtin_scenario_path("short_exact_map")))
    return write_kmall_pings(islice(pings, 20), folder / "tow.kmall"), write_npz(grid, folder / "map.npz")


def _run(survey, fixes, tmp_path, capsys) -> tuple[int, str]:
    path, map_path = survey
    code = main(["run", "--survey", str(path), "--bathy", str(map_path), "--usbl-fixes", str(fixes), "--out", str(tmp_path / "out")])
    assert not (tmp_path / "out").exists()
    return code, capsys.readouterr().err


def test_a_file_without_a_usable_fix_is_named_with_what_was_read(survey, tmp_path, capsys):
    fixes = tmp_path / "fixes.txt"
    bad = json_input_line(UsblFix(EPOCH_S + 5.0, 0.0, 0.0, 100.0, 0.0, 1.0, 0.0))  # a variance of zero: no covariance
    fixes.write_text(f"not a fix\n{bad}\n$GPGGA,garbled*00\n")
    code, err = _run(survey, fixes, tmp_path, capsys)
    assert code == 1 and "no USBL fix in it" in err and str(fixes) in err
    assert "JSON usbl line whose covariance is no covariance (skipped): 1" in err


def test_a_missing_fixes_file_is_named(survey, tmp_path, capsys):
    code, err = _run(survey, tmp_path / "absent.jsonl", tmp_path, capsys)
    assert code == 1 and "absent.jsonl" in err


def test_usbl_fixes_belong_to_a_survey(tmp_path, capsys):
    fixes = tmp_path / "fixes.jsonl"
    fixes.write_text(json_input_line(UsblFix(EPOCH_S, 0.0, 0.0, 100.0, 4.0, 4.0, 0.0)) + "\n")
    assert main(["run", "short", "--usbl-fixes", str(fixes), "--out", str(tmp_path / "out")]) == 2
    assert "--usbl-fixes" in capsys.readouterr().err and not (tmp_path / "out").exists()


def test_vendor_sentences_without_a_zda_or_a_sonar_clock_are_counted_and_refused(tmp_path):
    fixes = tmp_path / "fixes.nmea"
    fixes.write_text(psonlld_sentence(UsblFix(EPOCH_S, 0.0, 0.0, 100.0, 0.0, 0.0, 0.0), major_m=2.0, minor_m=1.0) + "\r\n")
    with pytest.raises(ValueError, match=r"USBL \$PSONLLD before any ZDA or \.kmall datagram \(no date; skipped\): 1"):
        read_usbl_fixes(fixes)
    (fix,), counts = read_usbl_fixes(fixes, sonar_time_s=EPOCH_S + 3600.0)  # the survey's first ping dates it
    assert fix.time_s == pytest.approx(EPOCH_S, abs=1e-6)
    assert counts["USBL $PSONLLD fixes dated by the sonar's datagram time (no ZDA)"] == 1


def test_sentences_without_error_fields_need_the_default_sigma(survey, tmp_path, capsys):
    from lost.host.live.usbl_nmea import psimssb_sentence

    fixes = tmp_path / "fixes.nmea"
    fixes.write_text("".join(psimssb_sentence(UsblFix(EPOCH_S + t, 0.0, 0.0, 100.0, 0.0, 0.0, 0.0)) + "\r\n" for t in (2.0, 7.0)))
    code, err = _run(survey, fixes, tmp_path, capsys)
    assert code == 1 and "without error fields and no [serve] usbl_default_sigma_m (skipped): 2" in err
    (fix, _), counts = read_usbl_fixes(fixes, sonar_time_s=EPOCH_S, default_sigma_m=4.0)
    assert (fix.sxx_m2, fix.syy_m2, fix.sxy_m2) == (16.0, 16.0, 0.0) and counts["USBL $PSIMSSB fixes given the default sigma"] == 2
    path, map_path = survey
    with_default = ["run", "--survey", str(path), "--bathy", str(map_path), "--usbl-fixes", str(fixes), "--usbl-default-sigma-m", "4"]
    assert main([*with_default, "--out", str(tmp_path / "used")]) == 0
    summary = json.loads((tmp_path / "used" / "summary.json").read_text())["usbl_fixes"]
    assert summary["fixes"] == 2 and summary["read"]["USBL $PSIMSSB fixes given the default sigma"] == 2
    capsys.readouterr()
    assert main(["run", "--survey", str(path), "--bathy", str(map_path), "--usbl-default-sigma-m", "4", "--out", str(tmp_path / "out")]) == 2
    assert "give --usbl-fixes FILE" in capsys.readouterr().err and not (tmp_path / "out").exists()
