"""`lost replay` into `lost serve` on localhost: the served estimates equal the batch path's (`lost run --survey`) record for
record, value for value; the log and the UDP outputs carry them; faults are counted into the summary, never a stop."""

from __future__ import annotations

import csv
import json
import math
from itertools import islice

import numpy as np
import pytest

from lost.host.cli import main
from lost.host.io import write_npz
from lost.host.io.kmall_write import write_kmall_pings
from lost.host.io.simulated import simulated_pings
from lost.host.live.outputs import nmea_checksum
from lost.host.scenario import builtin_scenario_path, load_scenario

PINGS = 120


@pytest.fixture(scope="module")
def tow(tmp_path_factory):
    """The first pings of the short tow on its own floor as a .kmall file, and the floor as the map."""
    folder = tmp_path_factory.mktemp("tow")
    grid, _, pings = simulated_pings(load_scenario(builtin_scenario_path("short_exact_map")))
    return write_kmall_pings(islice(pings, PINGS), folder / "tow.kmall"), write_npz(grid, folder / "map.npz")


@pytest.fixture(scope="module")
def batch_rows(tow, tmp_path_factory):
    """`lost run --survey`'s track.csv rows on the tow, with the served runs' settings."""
    path, map_path = tow
    out = tmp_path_factory.mktemp("batch") / "batch"
    arguments = ["run", "--survey", str(path), "--bathy", str(map_path), "--record-s", "5", "--window-s", "20", "--patch-centre", "soundings",
                 "--start-offset", "30,-20", "--dr-bias", "0.1,0.05", "--estimator", "all", "--out", str(out)]
    assert main(arguments) == 0
    with open(out / "track.csv") as stream:
        return list(csv.DictReader(stream))


def _cell(value) -> str:
    return "" if value is None else f"{value:.3f}"


def _assert_log_is_the_batch_runs(log: list[dict], rows: list[dict]) -> None:
    assert len(log) == len(rows) > 10
    for line, row in zip(log, rows, strict=True):
        assert f"{line['t_s']:.3f}" == row["t_s"]
        lost = line["estimates"]["lost"]
        assert (_cell(lost["east_m"]), _cell(lost["north_m"])) == (row["est_x_m"], row["est_y_m"])
        for name in ("pmf", "pf"):
            served = line["estimates"][name]
            cells = [_cell(served[k]) for k in ("east_m", "north_m", "sxx_m2", "syy_m2", "sxy_m2")] + [str(int(served["usable"])), served["stage"]]
            assert cells == [row[f"{name}_{k}"] for k in ("x_m", "y_m", "sxx", "syy", "sxy", "usable", "stage")], (line["record"], name)


def test_served_estimates_equal_the_batch_runs_record_for_record(tow, batch_rows, serve_replay, tmp_path, capsys):
    out, datagrams = serve_replay(tow, tmp_path)
    rows = batch_rows
    capsys.readouterr()
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    _assert_log_is_the_batch_runs(log, rows)
    # Every estimate went out twice per record and estimator: a JSON line and a $LOEST sentence with its checksum.
    lines = [json.loads(d) for d in datagrams if d.startswith(b"{")]
    sentences = [d.decode().strip() for d in datagrams if d.startswith(b"$LOEST")]
    assert len(lines) == len(sentences) == 3 * len(log)
    assert [(x["record"], x["estimator"]) for x in lines] == [(n, e) for n in range(len(log)) for e in ("lost", "pmf", "pf")]
    for served in lines:
        assert served == {"record": served["record"], "time_utc_s": served["time_utc_s"], "t_s": served["t_s"], "estimator": served["estimator"],
                          **log[served["record"]]["estimates"][served["estimator"]]}
    for sentence in sentences:
        body, checksum = sentence[1:].split("*")
        assert nmea_checksum(body) == checksum and len(body.split(",")) == 10
    summary = json.loads((out / "summary.json").read_text())
    assert summary["ended"].startswith("no datagram") and summary["records"] == len(log)
    assert summary["latency_ms"]["count"] == len(log) - 1  # the last record is closed by the end, not by a ping
    assert not [reason for reason, n in summary["received"].items() if n and ("skipped" in reason or "lost" in reason or "missing" in reason)]


def test_the_served_values_are_the_batch_navigations_to_the_bit(tow, tmp_path, capsys):
    """The same records through navigate() (the batch path's engine) and through the live navigator: equal floats."""
    from lost.host.cli.common import map_uncertainty
    from lost.host.io import read_grid
    from lost.host.io.survey import open_survey
    from lost.host.io.survey_records import SurveyRecorder, survey_records
    from lost.host.live.navigator import LiveNavigator
    from lost.host.live.receiver import LiveDecoder
    from lost.host.live.stream import live_datagrams
    from lost.host.nav import NavParameters, navigate

    path, map_path = tow
    params = NavParameters()
    grid, _ = map_uncertainty(read_grid(map_path), params)

    def recorder():
        return SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=5.0, window_s=20.0, dr_bias_mps=(0.1, 0.05),
                              start_offset_m=(30.0, -20.0), patch_centre="soundings")

    result = navigate(survey_records(open_survey(path, crs=grid.crs), recorder()), grid, params, estimators=("pmf", "pf"))
    live = LiveNavigator(grid, params, ("pmf", "pf"), recorder())
    decoder, served = LiveDecoder(), []
    for datagram in live_datagrams(open_survey(path)):
        for value in decoder.feed(datagram.payload):
            served += live.add(value) if hasattr(value, "beams") else []
    served += live.finish()
    for name in ("pmf", "pf"):
        mine = [e for e in served if e.estimator == name]
        track = result.tracks[name]
        assert len(mine) == len(track.position)
        np.testing.assert_array_equal([(e.east_m, e.north_m) for e in mine], track.position)
        np.testing.assert_array_equal([e.covariance_m2 for e in mine], track.covariance[:, [0, 1, 0], [0, 1, 1]])
        assert [e.usable for e in mine] == list(track.usable)
    capsys.readouterr()


def test_pings_reordered_on_the_way_are_put_back_in_time_order_and_served_as_the_batch_run(tow, batch_rows, serve_replay, tmp_path, capsys):
    """10 % of datagrams sent 8 later (a ping is 6 datagrams): pings complete out of order; the 1.5 s buffer restores the batch run."""
    out, _ = serve_replay(tow, tmp_path, ["--reorder", "0.1", "--reorder-by", "8", "--seed", "4"], reorder_lag_s=1.5,
                          reorder_hold_s=1.5)
    replayed = capsys.readouterr().out
    assert int(replayed.split(" reordered")[0].rsplit(" ", 1)[1]) > 10
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reorder_lag_s"] == summary["reorder_hold_s"] == 1.5 and not any("late" in reason for reason in summary["server"])
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    _assert_log_is_the_batch_runs(log, batch_rows)


def test_lost_duplicated_reordered_and_malformed_datagrams_are_counted_into_the_summary_never_a_stop(tow, serve_replay, tmp_path, capsys):
    junk = (b"\x00\x01 not a datagram", b"$GPGGA,garbled*00\r\n", (40).to_bytes(4, "little") + b"#MRZ" + bytes(28))
    out, _ = serve_replay(tow, tmp_path, ["--loss", "0.05", "--reorder", "0.05", "--duplicate", "0.05", "--seed", "3"], junk=junk,
                           estimators=["lost"])
    replayed = capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    received = summary["received"]
    assert received["datagram of neither .kmall, NMEA, PD6 nor JSON (skipped)"] == 1
    assert received["kmall #MRZ datagram whose length fields disagree with its size (skipped)"] == 1
    assert sum(n for reason, n in received.items() if "checksum" in reason or "NMEA" in reason) >= 1
    drawn = next(line for line in replayed.splitlines() if line.startswith("faults (seed 3)")).split("(.kmall ")[1]
    assert received["duplicate kmall datagram (skipped)"] == int(drawn.split(", ")[1].split(" duplicated")[0]) > 0
    assert received["pings missing from the ping counter's sequence"] > 0
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    assert summary["ended"].startswith("no datagram") and len(log) == summary["records"] >= PINGS // 5 - 2
    assert summary["methods"]["lost"]["usable_fraction"] > 0.5  # the clean replay: 0.875


def test_a_silent_sonar_and_pings_without_beams_are_stepped_as_dead_reckoning_and_counted(tow):
    from dataclasses import replace

    from lost.host.io import read_grid
    from lost.host.io.survey import open_survey
    from lost.host.io.survey_records import SurveyRecorder
    from lost.host.live.navigator import LiveNavigator
    from lost.host.nav import NavParameters

    path, map_path = tow
    grid = read_grid(map_path)
    live = LiveNavigator(grid, NavParameters(), ("pf",), SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=5.0,
                                                                                window_s=20.0, patch_centre="soundings"))
    pings = list(open_survey(path))
    start = pings[0].time_s
    served = []
    for ping in pings:
        age = ping.time_s - start
        if 40 <= age < 60:  # the sonar silent for 20 s: four intervals without a ping
            continue
        if 80 <= age < 110:  # pinging, but no bottom detected: the three records whose 20 s window holds no beam have no patch
            ping = replace(ping, valid=np.zeros_like(ping.valid))
        served += live.add(ping)
    served += live.finish()
    assert live.counts["record intervals without a ping (the sonar silent)"] == 4
    assert live.counts["records without a patch (dead reckoning)"] == 3  # at 99, 104 and 109 s
    assert len(served) == live.counts["records stepped"] == len({math.floor((p.time_s - start) / 5) for p in pings}) - 4
    assert all(np.isfinite(e.east_m) and np.isfinite(e.covariance_m2[0]) for e in served[1:])
    assert {e.stage for e in served if 95 <= e.t_s < 110} == {"dead_reckoning"}
