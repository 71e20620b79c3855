"""The vehicle's sensors on the network: PD6 and JSON lines read back to their precision, and the records they amend."""

from __future__ import annotations

import math
from collections import Counter
from itertools import islice

import numpy as np
import pytest

from lost.host.io.simulated import EPOCH_S, simulated_pings
from lost.host.io.survey_records import SurveyRecorder
from lost.host.live.inputs import DepthReading, DvlVelocity, Pd6Decoder, UsblFix, json_input_line, pd6_sentences
from lost.host.live.navigator import LiveNavigator
from lost.host.live.receiver import LiveDecoder
from lost.host.live.stream import live_datagrams, vehicle_datagrams
from lost.host.nav import NavParameters
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate


def test_a_pd6_ensemble_reads_back_to_its_precision():
    counts = Counter()
    decoder = Pd6Decoder(counts)
    time_s = EPOCH_S + 86_399.37  # the last second of a day, to the hundredth
    lines = pd6_sentences(time_s, -1.23449, 0.0004, 712.34)
    assert lines[0].startswith(":TS,26010123595937,") and lines[1] == ":BE,-01234,+00000,+00000,A"
    values = [value for line in [":SA,+01.20,-00.50,087.30", *lines, ":BD,+00000012.34,-00000001.20,+00000000.00,0060.12,000.00"]
              for value in decoder.feed(line)]
    assert values == [DepthReading(time_s, 712.3), DvlVelocity(time_s, -1.234, 0.0)]
    assert counts["PD6 :SA lines (not used)"] == counts["PD6 :BD lines (not used)"] == 1


def test_json_lines_read_back_exactly():
    values = [DvlVelocity(EPOCH_S + 0.5, 0.125, -1.5), DepthReading(EPOCH_S + 1.0, 712.25),
              UsblFix(EPOCH_S + 2.0, 0.0123456789, -0.98765, 700.0, 6.25, 4.0, -0.5)]
    decoder = LiveDecoder()
    assert decoder.feed("\n".join(json_input_line(v) for v in values).encode()) == values


@pytest.fixture(scope="module")
def tow_with_dvl(tmp_path_factory):
    """200 s of the short tow with a DVL on the vehicle (the simulator's own: 0.05 m/s noise, 2 % dropouts)."""
    text = builtin_scenario_path("short_exact_map").read_text().replace("has_velocity_sensor = false", "has_velocity_sensor = true")
    path = tmp_path_factory.mktemp("dvl") / "dvl_tow.toml"
    path.write_text(text.replace("duration_s = 600", "duration_s = 200"))
    scenario = load_scenario(path)
    grid, crs, pings = simulated_pings(scenario)
    _, records = simulate(scenario)
    return grid, crs, list(pings), records


@pytest.mark.parametrize("dvl_format", ["pd6", "json"])
def test_the_dvl_sent_by_replay_moves_the_records_and_its_depth_goes_into_them(tow_with_dvl, dvl_format):
    grid, crs, pings, records = tow_with_dvl
    recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=5.0, window_s=20.0, patch_centre="soundings")
    navigator, decoder = LiveNavigator(grid, NavParameters(), ("pf",), recorder), LiveDecoder()
    served = []
    for datagram in live_datagrams(pings, vehicle=vehicle_datagrams(records, crs, dvl_format=dvl_format, epoch_s=EPOCH_S)):
        for value in decoder.feed(datagram.payload):
            if isinstance(value, DvlVelocity | DepthReading):
                navigator.add_sensor(value)
            elif hasattr(value, "beams"):
                served += navigator.add(value)
    served += navigator.finish()
    assert len(served) == 40 and [e.velocity_source for e in served] == ["positions"] + ["dvl"] * 39
    assert navigator.counts["records on the DVL's velocity"] == 39 and navigator.counts["records at the depth sensor's depth"] == 40
    t = records.t_s
    for before, estimate in zip(served, served[1:], strict=False):
        inside = (t > before.t_s) & (t <= estimate.t_s) & np.isfinite(records.vel_x_mps)
        sent = np.array([records.vel_x_mps[inside].mean(), records.vel_y_mps[inside].mean()])
        np.testing.assert_allclose(estimate.velocity_mps, sent, atol=5e-4 + 1e-9)  # PD6 carries mm/s
        assert estimate.vehicle_depth_m == pytest.approx(records.vehicle_depth_m[t == estimate.t_s][0], abs=0.05 + 1e-9)
    # The loop closed: the DVL's velocity is the vehicle's true one within the simulator's noise (0.05 m/s a reading).
    true_velocity = np.array([np.subtract(*[(r.truth_east_m, r.truth_north_m) for r in (b, a)]) / (b.t_s - a.t_s)
                              for a, b in zip(served, served[1:], strict=False)]).reshape(-1, 2)
    error = np.array([e.velocity_mps for e in served[1:]]) - true_velocity
    assert np.sqrt(np.mean(error**2)) < 0.05 and not math.isnan(served[-1].east_m)


def test_a_dvl_that_goes_silent_leaves_the_records_on_the_differenced_positions_counted(tow_with_dvl):
    grid, crs, pings, records = tow_with_dvl
    recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=5.0, window_s=20.0)
    navigator, decoder = LiveNavigator(grid, NavParameters(), ("pmf",), recorder), LiveDecoder()
    vehicle = [d for d in vehicle_datagrams(records, crs, epoch_s=EPOCH_S) if d.time_s < EPOCH_S + 100.0]  # silent from 100 s
    served = []
    for datagram in live_datagrams(islice(pings, 150), vehicle=vehicle):
        for value in decoder.feed(datagram.payload):
            if isinstance(value, DvlVelocity | DepthReading):
                navigator.add_sensor(value)
            elif hasattr(value, "beams"):
                served += navigator.add(value)
    served += navigator.finish()
    silent = [e for e in served if e.t_s >= 100.0]
    assert {e.velocity_source for e in silent} == {"positions"} and {e.velocity_source for e in served[1:] if e.t_s < 100.0} == {"dvl"}
    assert navigator.counts["records without a DVL velocity in their interval (differenced positions)"] == len(silent) > 5
    before = [e for e in served if e.t_s < 100.0][-1]
    for a, b in zip([before, *silent], silent, strict=False):  # the pings' positions differenced: the truth here (no bias)
        np.testing.assert_allclose(b.velocity_mps, np.subtract((b.truth_east_m, b.truth_north_m), (a.truth_east_m, a.truth_north_m)) / (b.t_s - a.t_s))
    assert all(math.isfinite(e.east_m) for e in served)


def test_the_live_navigator_takes_the_maps_settings_of_its_parameters(tow_with_dvl):
    """The map the served navigation prepares is the batch navigation's: the same depth step and hole share."""
    from dataclasses import replace

    grid = tow_with_dvl[0]
    params = replace(NavParameters(), max_hole_share=0.3)
    recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=5.0, window_s=20.0)
    navigator = LiveNavigator(grid, params, ("pmf",), recorder)
    assert navigator.prepared.max_hole_share == 0.3
