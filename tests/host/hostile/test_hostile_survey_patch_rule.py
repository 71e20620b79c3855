"""`lost run --survey --patch-rule` on bad input: a rule with a patch centre it sets itself, an unknown rule, the flag without --survey."""

from __future__ import annotations

from dataclasses import replace

import pytest

from lost.host.cli import main
from lost.host.io import write_npz
from lost.host.io.kongsberg_all import write_all_pings
from lost.host.io.simulated import simulated_pings
from lost.host.scenario import builtin_scenario_path, load_scenario


@pytest.fixture(scope="module")
def survey(tmp_path_factory):
    folder = tmp_path_factory.mktemp("patch_rule")
    grid, _, pings = simulated_pings(replace(load_scenario(builtin_scenario_path("short_exact_map")), duration_s=20))
    return write_all_pings(pings, folder / "short.all"), write_npz(grid, folder / "map.npz")


def test_the_behind_rule_with_a_patch_centre_is_refused_and_nothing_is_written(survey, tmp_path, capsys):
    path, map_path = survey
    out = tmp_path / "run"
    code = main(["run", "--survey", str(path), "--bathy", str(map_path), "--patch-rule", "behind", "--patch-centre", "soundings",
                 "--out", str(out)])
    assert code == 2  # a usage error, as the flags' other misuses are
    err = capsys.readouterr().err
    assert "--patch-rule behind centres each patch on its centre ping: --patch-centre soundings cannot be given with it" in err
    assert err.count("\n") == 1 and not out.exists()


def test_an_unknown_rule_and_the_rule_without_a_survey_are_usage_errors(survey, tmp_path, capsys):
    path, map_path = survey
    with pytest.raises(SystemExit) as stop:
        main(["run", "--survey", str(path), "--bathy", str(map_path), "--patch-rule", "latest", "--out", str(tmp_path / "run")])
    assert stop.value.code == 2 and "argument --patch-rule: invalid choice: 'latest'" in capsys.readouterr().err
    assert main(["run", "short_exact_map", "--patch-rule", "window", "--out", str(tmp_path / "scenario")]) == 2
    assert "--patch-rule" in capsys.readouterr().err and not (tmp_path / "scenario").exists()
