"""The ``lost`` command: run, demo and correlate, end to end on files."""

import csv
import json
import math
import re
from dataclasses import replace

import numpy as np
import pytest

from lost.host.cli import main
from lost.host.grid import Grid
from lost.host.scenario import builtin_scenario_path
from lost.host.terrain import synthetic_terrain


def test_run_a_scenario_writes_the_track_summary_and_plots(tmp_path, capsys):
    out = tmp_path / "short"
    assert main(["run", str(builtin_scenario_path("short")), "--out", str(out)]) == 0
    assert {p.name for p in out.iterdir()} == {"track.csv", "summary.json", "map.png", "error.png", "lost-run.json"}
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["methods"]) == {"lost", "layback", "dead_reckoning", "pmf", "pf"}
    for stats in summary["methods"].values():
        assert {"rms_m", "p95_m", "max_m"} <= set(stats)
    for name in ("pmf", "pf"):
        assert {"nees_in_band", "usable_fraction", "false_fixes", "ms_per_update", "convergence_time_s"} <= set(summary["methods"][name])
    assert summary["parameters"]["backend"] == "software"
    assert (out / "map.png").read_bytes()[:4] == b"\x89PNG"
    printed = capsys.readouterr().out
    assert "LOST converged after" in printed and "layback" in printed


def test_one_estimator_writes_its_track_with_covariance(tmp_path, capsys):
    out = tmp_path / "pmf"
    assert main(["run", "short_exact_map", "--estimator", "pmf", "--out", str(out), "--no-plots"]) == 0
    assert {p.name for p in out.iterdir()} == {"track.csv", "summary.json", "lost-run.json"}  # --no-plots: no figure drawn
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["methods"]) == {"layback", "dead_reckoning", "pmf"} and summary["convergence"]["estimator"] == "pmf"
    with open(out / "track.csv", newline="") as stream:
        rows = list(csv.DictReader(stream))
    assert {"pmf_x_m", "pmf_y_m", "pmf_sxx", "pmf_syy", "pmf_sxy", "pmf_usable", "pmf_nis", "pmf_stage"} <= set(rows[0])
    assert "pf_x_m" not in rows[0]
    assert {r["pmf_stage"] for r in rows} >= {"initialization", "acquisition", "tracking", "dead_reckoning"}
    late = [r for r in rows if r["pmf_stage"] == "tracking"][-1]
    assert float(late["pmf_sxx"]) > 0 and float(late["pmf_syy"]) > 0 and late["pmf_usable"] == "1"
    assert float(late["pmf_error_m"]) < 3.0 * math.sqrt(float(late["pmf_sxx"]) + float(late["pmf_syy"]))
    printed = capsys.readouterr().out
    assert "pmf converged after" in printed and "wrote" in printed and ".png" not in printed
    assert {r["pmf_depth_bias_m"] for r in rows} == {""}  # the patch form has no depth bias to report
    # The velocity bias it learned, with its 1-sigma (wide on this tow: its "bias" is the towfish's lag, walking fast).
    bias, sigma = summary["methods"]["pmf"]["velocity_bias_mps"], summary["methods"]["pmf"]["velocity_bias_sigma_mps"]
    assert [float(rows[-1][f"pmf_velocity_bias_{axis}_mps"]) for axis in "en"] == pytest.approx(bias, abs=1e-4)
    assert min(sigma) > 0.0 and [float(rows[-1][f"pmf_velocity_bias_sigma_{axis}_mps"]) for axis in "en"] == pytest.approx(sigma, abs=1e-4)


def test_run_by_builtin_name_with_backend_and_matching(tmp_path):
    out = tmp_path / "point"
    assert main(["run", "short", "--out", str(out), "--backend", "model", "--matching", "point", "--no-plots"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["parameters"]["backend"] == "model" and summary["parameters"]["matching"] == "point"


def test_set_overrides_the_scenarios_navigation_parameters(tmp_path, capsys):
    out = tmp_path / "patent"
    args = ["run", "short", "--out", str(out), "--set", "cross_damping_per_s=none", "--set", "initial_offset_m=[10, -20]",
            "--set", "layback_model=cable", "--no-plots"]
    assert main(args) == 0
    parameters = json.loads((out / "summary.json").read_text())["parameters"]
    # The shipped scenario damps the tracker; `none` restores the patent's (1 - u).
    assert parameters["cross_damping_per_s"] is None
    assert list(parameters["initial_offset_m"]) == [10.0, -20.0] and parameters["layback_model"] == "cable"
    capsys.readouterr()
    assert main(["run", "short", "--out", str(out), "--set", "kay=3"]) == 2
    assert "--set names no navigation parameter: kay" in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["--log", "nav.csv"], "--log needs the map it is navigated on: --bathy grid.nc"),
    (["--bathy", "grid.nc"], "give its navigation log (--log nav.csv) or survey files (--survey FILE...)"),
    ([], "give a scenario (a TOML file, or a shipped one's name: lost run --list), or --log nav.csv and --bathy grid.nc, or --survey"),
    (["--log", "nav.csv", "--bathy", "grid.nc", "--seed", "3"], "--seed draws a simulated scenario anew: give a scenario"),
], ids=["log_alone", "bathy_alone", "nothing", "seed_of_a_log"])
def test_run_needs_a_scenario_or_log_and_bathy(capsys, argv, message):
    assert main(["run", *argv]) == 2
    assert message in capsys.readouterr().err


def test_a_scenario_with_an_unknown_navigation_field_is_refused(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text("duration_s = 10\n[navigation]\nkay = 3\n")
    assert main(["run", str(path), "--out", str(tmp_path / "o")]) == 1
    assert "kay" in capsys.readouterr().err


def _map_file(tmp_path):
    from lost.host.io import write_npz

    depth = synthetic_terrain((60, 70), seed=11, roughness_m=10.0, hurst=0.5)
    grid = Grid(depth, 1000.0, 2000.0, 10.0)
    return depth, write_npz(grid, tmp_path / "map.npz")


def test_correlate_files_prints_best_fit_and_runner_up(tmp_path, capsys):
    depth, map_path = _map_file(tmp_path)
    patch = depth[20:30, 33:43] + 4.0
    patch[0, 0] = np.nan
    np.save(tmp_path / "patch.npy", patch)
    assert main(["correlate", str(map_path), str(tmp_path / "patch.npy"), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["best"]["i"] == 20 and result["best"]["j"] == 33 and result["best"]["value"] <= 99 * 99
    assert result["valid_nodes"] == 99 and result["runner_up"]["value"] > result["best"]["value"]
    np.savetxt(tmp_path / "patch.csv", patch, delimiter=",")
    assert main(["correlate", str(map_path), str(tmp_path / "patch.csv"), "--backend", "model"]) == 0
    printed = capsys.readouterr().out
    assert "best fit   (i, j) = (20, 33)" in printed and "centre x = 1375.0 m, y = 2245.0 m" in printed


def test_correlate_rejects_a_bad_patch_file(tmp_path, capsys):
    _, map_path = _map_file(tmp_path)
    (tmp_path / "patch.json").write_text("[]")
    assert main(["correlate", str(map_path), str(tmp_path / "patch.json")]) == 1
    assert "a patch must be .csv, .txt, .npy, .npz of depths in metres, got patch.json" in capsys.readouterr().err


def test_demo_runs_into_its_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["demo"]) == 0
    summary = json.loads((tmp_path / "runs" / "demo" / "summary.json").read_text())
    assert summary["name"] == "demo" and summary["convergence"]["converged"]
    assert summary["methods"]["lost"]["rms_m"] < 5.0


def test_run_a_recorded_tow_from_log_sonar_and_grid_files(tmp_path, capsys):
    """The simulator's short tow written as files in NAV-io's documented layout, then read back by `lost run --log`."""
    from lost.host.io import write_npz
    from lost.host.scenario import load_scenario, simulate

    grid, records = simulate(load_scenario(builtin_scenario_path("short_exact_map")))
    map_path = write_npz(grid, tmp_path / "map.npz")
    columns = {
        "t_s": records.t_s, "x_m": records.ship_x_m, "y_m": records.ship_y_m, "ship_heading_deg": records.ship_heading_deg,
        "vehicle_depth_m": records.vehicle_depth_m, "altitude_m": records.altitude_m, "vel_x_mps": records.vel_x_mps,
        "vel_y_mps": records.vel_y_mps, "cable_out_m": records.cable_out_m, "slant_range_m": records.slant_range_m,
        "truth_x_m": records.truth_x_m, "truth_y_m": records.truth_y_m,
    }
    np.savetxt(tmp_path / "nav.csv", np.column_stack(list(columns.values())), delimiter=",", header=",".join(columns), comments="")
    soundings = []
    for n, patch in enumerate(records.sonar):
        if patch is None:
            continue
        h, w = patch.depth_m.shape
        north, east = np.meshgrid((np.arange(h) - (h - 1) / 2) * patch.node_m, (np.arange(w) - (w - 1) / 2) * patch.node_m, indexing="ij")
        keep = np.isfinite(patch.depth_m)
        soundings.append(np.column_stack([np.full(keep.sum(), records.t_s[n]), east[keep], north[keep], patch.depth_m[keep]]))
    np.savetxt(tmp_path / "sonar.csv", np.vstack(soundings), delimiter=",", header="t_s,east_m,north_m,depth_m", comments="")

    out = tmp_path / "recorded"
    code = main(["run", "--log", str(tmp_path / "nav.csv"), "--bathy", str(map_path), "--sonar", str(tmp_path / "sonar.csv"), "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["name"] == "nav" and summary["truth_known"]
    assert summary["convergence"]["converged"] and summary["methods"]["lost"]["rms_m"] < 7.0
    assert summary["methods"]["layback"]["rms_m"] > 10 * summary["methods"]["lost"]["rms_m"]


def test_a_recorded_realtime_swath_is_centred_on_its_soundings(tmp_path, capsys):
    """A real-time swath (patches behind the vehicle) logged without patch centres: --patch-centre soundings."""
    import pandas as pd

    from lost.host.io import write_npz
    from lost.host.io.navlog import write_navlog
    from lost.host.scenario import exact_map, load_scenario, simulate

    scenario = exact_map(load_scenario(builtin_scenario_path("demo")))  # its 10 m patch on the floor's nodes
    grid, records = simulate(replace(scenario, duration_s=600.0))
    map_path = write_npz(grid, tmp_path / "map.npz")
    write_navlog(records, tmp_path / "nav.csv", sonar=tmp_path / "sonar.csv")
    log = pd.read_csv(tmp_path / "nav.csv")
    # Once the swath reaches half a patch diagonal back (the first minute), every patch lies that far behind.
    assert np.hypot(log["patch_east_m"][60:], log["patch_north_m"][60:]).min() > 70.0
    log.drop(columns=["patch_east_m", "patch_north_m"]).to_csv(tmp_path / "nav.csv", index=False)
    files = ["--log", str(tmp_path / "nav.csv"), "--bathy", str(map_path), "--sonar", str(tmp_path / "sonar.csv")]

    assert main(["run", *files, "--patch-centre", "soundings", "--patch-shape", "10x10", "--out", str(tmp_path / "a")]) == 0
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert summary["convergence"]["converged"] and summary["methods"]["lost"]["rms_m"] < 5.0
    # Centred on the vehicle, most of each patch's soundings fall beyond it, and the report says so.
    capsys.readouterr()
    assert main(["run", *files, "--out", str(tmp_path / "b")]) == 0
    used, outside = (int(x) for x in re.search(r"(\d+) gridded into .*?\n.*?not used: (\d+) beyond the patch", capsys.readouterr().out, re.S).groups())
    assert outside > used
    with pytest.raises(SystemExit):
        main(["run", *files, "--patch-shape", "10by10"])
    assert "expected ROWSxCOLS" in capsys.readouterr().err


def test_long_runs_get_a_progress_bar_that_passes_every_record():
    from lost.host.cli import PROGRESS_ITEMS, progress_bar

    assert progress_bar(PROGRESS_ITEMS, "navigating") is None
    wrap = progress_bar(PROGRESS_ITEMS + 1, "navigating")
    assert list(wrap(range(PROGRESS_ITEMS + 1))) == list(range(PROGRESS_ITEMS + 1))


def test_correlate_never_places_the_patch_on_a_hole(tmp_path, capsys):
    from lost.host.io import write_npz

    depth = synthetic_terrain((60, 70), seed=11, roughness_m=10.0, hurst=0.5)
    patch = depth[20:30, 33:43].copy()
    holed = depth.copy()
    holed[25, 40] = np.nan
    map_path = write_npz(Grid(holed, 0.0, 0.0, 10.0), tmp_path / "holed.npz")
    np.save(tmp_path / "patch.npy", patch)
    assert main(["correlate", str(map_path), str(tmp_path / "patch.npy"), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["excluded_placements"] == 100  # the 10 x 10 placements whose window covers node (25, 40)
    best = result["best"]
    assert not (16 <= best["i"] <= 25 and 31 <= best["j"] <= 40)


def test_the_rtl_backend_says_first_that_its_first_build_takes_minutes(capsys):
    """Before any work (here a refused --set, so nothing is built), on stderr so that stdout stays the command's report."""
    assert main(["run", "short", "--backend", "rtl", "--set", "kay=3"]) == 2
    captured = capsys.readouterr()
    first, last = captured.err.strip().splitlines()
    assert first.startswith("--backend rtl: the device's Verilog runs on Verilator; its first build") and "kay" in last
    assert "Verilator" not in captured.out


def test_correlate_gives_no_ratio_against_an_exact_fit(tmp_path, capsys):
    from lost.host.grid import Grid
    from lost.host.io.grids import write_npz

    rng = np.random.default_rng(3)
    depths = 1000.0 + np.cumsum(np.cumsum(rng.normal(size=(30, 30)), 0), 1) * 0.5
    write_npz(Grid(depths, 0.0, 0.0, 10.0), tmp_path / "map.npz")
    np.save(tmp_path / "exact.npy", depths[5:13, 9:17])
    np.save(tmp_path / "noisy.npy", depths[5:13, 9:17] + rng.normal(0.0, 0.2, size=(8, 8)))
    assert main(["correlate", str(tmp_path / "map.npz"), str(tmp_path / "exact.npy")]) == 0
    assert "ratio - (the best fit is exact, V = 0)" in capsys.readouterr().out
    assert main(["correlate", str(tmp_path / "map.npz"), str(tmp_path / "noisy.npy")]) == 0
    ratio = float(capsys.readouterr().out.split("ratio ")[1].split()[0])
    assert ratio > 1.0


def test_a_negative_seed_is_refused_by_name(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["run", "short", "--seed", "-1"])
    assert exit_.value.code == 2 and "a seed is at least 0, got -1" in capsys.readouterr().err


def test_a_scenario_runs_with_a_campaigns_seed_into_its_own_folder(tmp_path, monkeypatch, capsys):
    from lost.host.campaign import scenario_with
    from lost.host.nav import NavParameters, navigate
    from lost.host.report import summarize
    from lost.host.scenario import load_scenario, simulate

    monkeypatch.chdir(tmp_path)
    assert main(["run", "short", "--seed", "3", "--estimator", "pmf", "--no-plots", "--set", "pmf_cells=48"]) == 0
    summary = json.loads((tmp_path / "runs" / "short-seed3" / "summary.json").read_text())
    scenario = scenario_with(load_scenario(builtin_scenario_path("short")), {"seed": 3, "navigation.pmf_cells": 48})
    grid, records = simulate(scenario)
    expected = summarize(navigate(records, grid, NavParameters(**scenario.navigation), estimators=("pmf",)), name="short", parameters={})
    assert summary["methods"]["pmf"]["rms_m"] == expected["methods"]["pmf"]["rms_m"]  # the campaign's run of seed 3
    assert main(["run", "short", "--estimator", "pmf", "--no-plots", "--set", "pmf_cells=48"]) == 0
    shipped = json.loads((tmp_path / "runs" / "short" / "summary.json").read_text())
    assert shipped["methods"]["pmf"]["rms_m"] != summary["methods"]["pmf"]["rms_m"]
