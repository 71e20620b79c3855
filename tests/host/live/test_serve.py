"""`lost replay` into `lost serve` on localhost: the served estimates equal the batch path's (`lost run --survey`) record for
record, value for value; the log and the UDP outputs carry them; faults are counted into the summary, never a stop."""

from __future__ import annotations

import csv
import json
import socket
import threading
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
SETTINGS = {"record_s": 5.0, "window_s": 20.0, "patch_centre": "soundings", "start_offset_m": [30.0, -20.0], "dr_bias_mps": [0.1, 0.05]}


@pytest.fixture(scope="module")
def tow(tmp_path_factory):
    """The first pings of the short tow on its own floor as a .kmall file, and the floor as the map."""
    folder = tmp_path_factory.mktemp("tow")
    grid, _, pings = simulated_pings(load_scenario(builtin_scenario_path("short_exact_map")))
    return write_kmall_pings(islice(pings, PINGS), folder / "tow.kmall"), write_npz(grid, folder / "map.npz")


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _settings(path, map_path, port, output_port, **extra) -> None:
    table = {"listen": f"127.0.0.1:{port}", "bathy": str(map_path), "estimators": ["lost", "pmf", "pf"], "outputs": [f"127.0.0.1:{output_port}"],
             "idle_stop_s": 1.5, "status_s": 0.5, **SETTINGS, **extra}
    lines = ["[serve]"] + [f"{key} = {json.dumps(value)}" for key, value in table.items()]
    path.write_text("\n".join(lines) + "\n")


def _serve_replay(tow, tmp_path, replay_options=(), **extra):
    """Serve on a free port while `lost replay` sends the tow; the run folder and the datagrams that came out."""
    path, map_path = tow
    port, listener = _free_port(), socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    listener.bind(("127.0.0.1", 0))
    listener.settimeout(0.2)
    config, out = tmp_path / "live.toml", tmp_path / "serve"
    _settings(config, map_path, port, listener.getsockname()[1], **extra)
    codes: list[int] = []
    server = threading.Thread(target=lambda: codes.append(main(["serve", "--config", str(config), "--out", str(out)])))
    server.start()
    received: list[bytes] = []
    stop = threading.Event()

    def listen():
        while not stop.is_set():
            try:
                received.append(listener.recv(65_535))
            except TimeoutError:
                continue

    listening = threading.Thread(target=listen)
    listening.start()
    try:
        import time

        time.sleep(1.0)  # the server reads its map and binds its port
        assert main(["replay", str(path), "--to", f"127.0.0.1:{port}", "--speed", "0", *replay_options]) == 0
        server.join(60)
    finally:
        stop.set()
        listening.join(5)
        listener.close()
    assert codes == [0]
    return out, received


def _batch(tow, tmp_path):
    path, map_path = tow
    out = tmp_path / "batch"
    arguments = ["run", "--survey", str(path), "--bathy", str(map_path), "--record-s", "5", "--window-s", "20", "--patch-centre", "soundings",
                 "--start-offset", "30,-20", "--dr-bias", "0.1,0.05", "--estimator", "all", "--out", str(out)]
    assert main(arguments) == 0
    with open(out / "track.csv") as stream:
        return list(csv.DictReader(stream))


def _cell(value) -> str:
    return "" if value is None else f"{value:.3f}"


def test_served_estimates_equal_the_batch_runs_record_for_record(tow, tmp_path, capsys):
    out, datagrams = _serve_replay(tow, tmp_path)
    rows = _batch(tow, tmp_path)
    capsys.readouterr()
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    assert len(log) == len(rows) > 10
    for line, row in zip(log, rows, strict=True):
        assert f"{line['t_s']:.3f}" == row["t_s"]
        lost = line["estimates"]["lost"]
        assert (_cell(lost["east_m"]), _cell(lost["north_m"])) == (row["est_x_m"], row["est_y_m"])
        for name in ("pmf", "pf"):
            served = line["estimates"][name]
            cells = [_cell(served[k]) for k in ("east_m", "north_m", "sxx_m2", "syy_m2", "sxy_m2")] + [str(int(served["usable"])), served["stage"]]
            assert cells == [row[f"{name}_{k}"] for k in ("x_m", "y_m", "sxx", "syy", "sxy", "usable", "stage")], (line["record"], name)
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
    from lost.host.cli.run import _map_uncertainty
    from lost.host.io import read_grid
    from lost.host.io.survey import open_survey
    from lost.host.io.survey_records import SurveyRecorder, survey_records
    from lost.host.live.navigator import LiveNavigator
    from lost.host.live.receiver import LiveDecoder
    from lost.host.live.stream import live_datagrams
    from lost.host.nav import NavParameters, navigate

    path, map_path = tow
    params = NavParameters()
    grid, _ = _map_uncertainty(read_grid(map_path), params)

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
