"""`lost serve` on the vehicle's own sensors: a scenario's DVL and depth replayed as PD6 steer the records; a USBL fix on a
second port is logged and given to the navigation."""

from __future__ import annotations

import json

import numpy as np

from lost.host.io import write_npz
from lost.host.io.simulated import EPOCH_S, simulated_pings
from lost.host.live.inputs import UsblFix, json_input_line
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate


def test_a_scenarios_dvl_and_depth_replayed_as_pd6_steer_the_served_records_and_a_usbl_fix_on_a_second_port_is_logged(serve_replay, tmp_path, capsys):
    """`lost replay SCENARIO.toml` sends the simulator's DVL and depth (PD6) with the pings; a USBL fix comes on the second port."""
    text = builtin_scenario_path("short_exact_map").read_text().replace("has_velocity_sensor = false", "has_velocity_sensor = true")
    scenario = tmp_path / "dvl_tow.toml"
    scenario.write_text(text.replace("duration_s = 600", "duration_s = 120"))
    grid, _, _ = simulated_pings(load_scenario(scenario))
    fix = UsblFix(EPOCH_S + 30.0, 0.0123, 0.0071, 700.5, 25.0, 16.0, 2.0)
    out, _ = serve_replay((scenario, write_npz(grid, tmp_path / "map.npz")), tmp_path, ["--dvl", "pd6"], two_ports=True,
                           junk=((json_input_line(fix) + "\n").encode(), b":BE,+00001,+00002,+00000,A\r\n"), estimators=["pmf"])
    replayed = capsys.readouterr().out
    assert "the vehicle's DVL and depth as PD6" in replayed and ", 120 of the vehicle's sensors" in replayed
    lines = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    assert lines[0] == {"usbl": {"time_utc_s": fix.time_s, "lat_deg": fix.lat_deg, "lon_deg": fix.lon_deg, "depth_m": fix.depth_m,
                                 "sxx_m2": 25.0, "syy_m2": 16.0, "sxy_m2": 2.0}}
    served = [line["estimates"]["pmf"] for line in lines[1:]]
    assert len(served) == 24 and [e["velocity_source"] for e in served] == ["positions"] + ["dvl"] * 23
    summary = json.loads((out / "summary.json").read_text())
    assert summary["server"]["USBL fixes received"] == 1 and summary["navigation"]["USBL fixes used"] == 1
    assert summary["received"]["PD6 :BE before any :TS (no time; skipped)"] == 1  # the stray line, before the replay began
    measured = int(np.isfinite(simulate(load_scenario(scenario))[1].vel_x_mps).sum())  # the simulator's DVL dropouts are sent as V
    assert summary["received"]["PD6 :BE lines"] == measured and summary["received"]["PD6 :TS lines"] == 120
    assert summary["received"]["PD6 :BE marked bad (status V or -32768; skipped)"] == 120 - measured
    assert summary["navigation"]["records on the DVL's velocity"] == 23
