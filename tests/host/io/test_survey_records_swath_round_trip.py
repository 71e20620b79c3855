"""A swath scenario's tow through a real format and back: the recorder's ``"behind"`` rule gives the scenario's own patches.

``simulated_pings`` writes a ``"swath"`` scenario's own soundings; the recorder, given the dead reckoning the scenario
placed them by (``swath_dead_reckoning_error``) and its real-time rule (``patch_rule="behind"``, ``window_s`` its
``max_window_s``), grids the scenario's patches: bit for bit from the pings never written, to the format's precision
from the ``.all`` file; and the scenario's records with the file's patches navigate as the scenario's own.
"""

from __future__ import annotations

import json
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from lost.host.cli import main
from lost.host.io import write_npz
from lost.host.io.crs import transformer
from lost.host.io.kongsberg_all import write_all_pings
from lost.host.io.simulated import simulated_pings, swath_dead_reckoning_error
from lost.host.io.survey import open_survey, project_ping
from lost.host.io.survey_records import SurveyRecorder, survey_records
from lost.host.nav import navigate, navigation_parameters
from lost.host.scenario import builtin_scenario_path, load_scenario
from lost.host.scenario.tow import simulate_with_swath

SECONDS = 200  # the centre settles 140 s behind the vehicle (half a 300 m patch's diagonal at 3 kn): 60 s of full patches


@pytest.fixture(scope="module")
def tow(tmp_path_factory):
    scenario = replace(load_scenario(builtin_scenario_path("demo")), duration_s=SECONDS)
    assert scenario.sensors["sonar"].mode == "swath" and scenario.sensors["sonar"].realtime
    grid, records, swath = simulate_with_swath(scenario)
    map_grid, crs, pings = simulated_pings(scenario)
    memory = list(pings)
    path = write_all_pings(iter(memory), tmp_path_factory.mktemp("swath_round_trip") / "demo.all")
    to_map = transformer("EPSG:4326", crs)
    memory = [project_ping(ping, to_map) for ping in memory]  # what open_survey does to a ping it reads
    return SimpleNamespace(scenario=scenario, grid=grid, records=records, swath=swath, memory=memory, read_back=list(open_survey(path, crs=crs)),
                           file=path, map=write_npz(map_grid, path.with_name("map.npz")))


def _patches(tow, pings):
    spec = tow.scenario.sensors["sonar"]
    recorder = SurveyRecorder(node_m=tow.grid.node_m, patch_shape=spec.shape, interval_s=spec.interval_s, window_s=spec.max_window_s,
                              patch_rule="behind", dead_reckoning_error=swath_dead_reckoning_error(tow.records, tow.swath))
    made = survey_records(iter(pings), recorder)
    assert len(made) == len(tow.records) == SECONDS
    return made.sonar


def test_the_pings_never_written_give_the_scenarios_patches_bit_for_bit(tow):
    for made, own in zip(_patches(tow, tow.memory), tow.records.sonar, strict=True):
        np.testing.assert_array_equal(made.depth_m, own.depth_m)
        assert made.centre_offset_m == pytest.approx(own.centre_offset_m, abs=1e-9)
        assert made.age_s == pytest.approx(own.age_s, abs=1e-9)


def test_the_files_patches_are_the_scenarios_to_the_formats_precision(tow):
    differences, changed, centres, ages = [], 0, [], []
    for made, own in zip(_patches(tow, tow.read_back), tow.records.sonar, strict=True):
        both = np.isfinite(made.depth_m) & np.isfinite(own.depth_m)
        changed += int(np.sum(np.isfinite(made.depth_m) != np.isfinite(own.depth_m)))
        differences.append(np.abs(made.depth_m - own.depth_m)[both])
        centres.append(np.hypot(*np.subtract(made.centre_offset_m, own.centre_offset_m)))
        ages.append(abs(made.age_s - own.age_s))
    differences, centres, ages = np.concatenate(differences), np.array(centres), np.array(ages)
    # Measured: median 5.5e-6 m, 99th percentile 1.5 cm, at most 8.5 cm (5.3 % of the nodes differ by over 1 mm, where a
    # rounding of 5 mm of position or 0.01 degree of heading moved a beam over a node's edge), 1 of 10,847 nodes filled. Over
    # 250 s one record took the ping beside the scenario's as its centre (1.7 m away: a ping 2 cm from half the diagonal).
    assert differences.size > 10_000
    assert np.median(differences) < 1e-4 and np.percentile(differences, 99) < 0.05
    assert changed / differences.size < 0.001
    same = centres < 0.05
    assert same.sum() >= SECONDS - 2 and np.all(centres < 3.0)
    # A patch's age is its soundings' mean: within a millisecond but where a ping at its edge was taken or left (under 0.01 s).
    assert np.median(ages[same]) < 1e-3 and np.all(ages[same] < 0.05)


def test_the_scenarios_records_with_the_files_patches_navigate_as_the_scenario(tow):
    grid, records = tow.grid, tow.records
    params = navigation_parameters(tow.scenario.navigation)
    own = navigate(records, grid, params, estimators=("pmf", "pf"))
    from_file = navigate(replace(records, sonar=_patches(tow, tow.read_back)), grid, params, estimators=("pmf", "pf"))
    pmf = np.hypot(*(from_file.tracks["pmf"].position - own.tracks["pmf"].position).T)
    pf = np.hypot(*(from_file.tracks["pf"].position - own.tracks["pf"].position).T)
    # Measured (30 m nodes): PMF median 1.6 mm, at most 4.5 cm (over 250 s: 8 cm, 0.13 m); the PF's draws follow the
    # patches' last bits: median 9 cm, at most 1.3 m (over 250 s: 0.12 m, 2.1 m).
    assert np.all(np.isfinite(pmf)) and np.all(np.isfinite(pf))
    assert np.median(pmf) < 0.01 and np.max(pmf) < 0.5
    assert np.median(pf) < 0.5 and np.percentile(pf, 99) < 3.0 and np.max(pf) < 5.0
    truth = np.column_stack([records.truth_x_m, records.truth_y_m])
    settled = slice(100, None)  # both converge within 70 s of the start
    for name in ("pmf", "pf"):
        rms = [float(np.sqrt(np.mean(np.sum((run.tracks[name].position[settled] - truth[settled]) ** 2, axis=1)))) for run in (own, from_file)]
        assert rms[0] < 10.0 and abs(rms[1] - rms[0]) < 0.1 * grid.node_m, (name, rms)


def test_the_behind_rule_is_refused_with_a_patch_centre_and_an_unknown_rule_is_named():
    with pytest.raises(ValueError, match="patch_rule 'behind' centres each patch on its centre ping"):
        SurveyRecorder(node_m=30.0, patch_shape=(10, 10), interval_s=1.0, patch_rule="behind", patch_centre="soundings")
    with pytest.raises(ValueError, match=r"patch_rule must be one of \('window', 'behind'\), got 'latest'"):
        SurveyRecorder(node_m=30.0, patch_shape=(10, 10), interval_s=1.0, patch_rule="latest")


def test_lost_run_survey_takes_the_behind_rule_and_says_so(tow, tmp_path, capsys):
    out = tmp_path / "run"
    code = main(["run", "--survey", str(tow.file), "--bathy", str(tow.map), "--record-s", "1", "--window-s", "300", "--patch-rule", "behind",
                 "--start-offset", "30,-20", "--estimator", "pmf", "--out", str(out)])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["survey"]["patch_rule"] == "behind" and summary["survey"]["window_s"] == 300
    assert summary["methods"]["pmf"]["rms_m"] < 10.0  # 30 m nodes: the start offset found within a third of a node
    capsys.readouterr()
    assert main(["run", "short_exact_map", "--patch-rule", "behind"]) == 2
    assert "--patch-rule" in capsys.readouterr().err
