"""Serving on localhost for the tests of `lost serve`: a free port, the settings file, `lost replay` into `lost serve`."""

from __future__ import annotations

import json
import socket
import threading
import time

import pytest

from lost.host.cli import main

#: The served runs' settings, `lost run --survey`'s of the batch comparison.
SETTINGS = {"record_s": 5.0, "window_s": 20.0, "patch_centre": "soundings", "start_offset_m": [30.0, -20.0], "dr_bias_mps": [0.1, 0.05]}


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_until_bound(port: int, timeout_s: float = 30.0) -> None:
    """Until the server has bound its port (a datagram sent before would be lost): binding it here fails then."""

    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            try:
                probe.bind(("127.0.0.1", port))
            except OSError:
                return
        time.sleep(0.05)
    raise AssertionError(f"lost serve did not bind port {port} in {timeout_s} s")


def _settings(path, map_path, port, output_port, serial=(), **extra) -> None:
    table = {"listen": f"127.0.0.1:{port}", "bathy": str(map_path), "estimators": ["lost", "pmf", "pf"], "outputs": [f"127.0.0.1:{output_port}"],
             "idle_stop_s": 1.5, "status_s": 0.5, **SETTINGS, **extra}
    lines = ["[serve]"] + [f"{key} = {json.dumps(value)}" for key, value in table.items()]
    for port_table in serial:
        lines += ["[[serial]]"] + [f"{key} = {json.dumps(value)}" for key, value in port_table.items()]
    path.write_text("\n".join(lines) + "\n")


def _serve_replay(tow, tmp_path, replay_options=(), junk: tuple[bytes, ...] = (), two_ports: bool = False, serial=(), before_replay=None,
                  **extra):
    """Serve on a free port while `lost replay` sends the tow; the run folder and the datagrams that came out.

    ``two_ports``: the server listens on a second port too, and ``junk`` goes there. ``serial``: ``[[serial]]`` tables;
    ``before_replay``: called once the server listens, before the replay starts.
    """
    path, map_path = tow
    port, listener = _free_port(), socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    junk_port = _free_port() if two_ports else port
    if two_ports:
        extra["listen"] = [f"127.0.0.1:{port}", f"127.0.0.1:{junk_port}"]
    listener.bind(("127.0.0.1", 0))
    listener.settimeout(0.2)
    config, out = tmp_path / "live.toml", tmp_path / "serve"
    _settings(config, map_path, port, listener.getsockname()[1], serial=serial, **extra)
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
        _wait_until_bound(port)
        _wait_until_bound(junk_port)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            for payload in junk:
                sender.sendto(payload, ("127.0.0.1", junk_port))
        if before_replay is not None:
            before_replay()
        assert main(["replay", str(path), "--to", f"127.0.0.1:{port}", "--speed", "0", *replay_options]) == 0
        server.join(60)
    finally:
        stop.set()
        listening.join(5)
        listener.close()
    assert codes == [0]
    return out, received




def batch_survey_run(map_path, pings_path, fixes_path, out) -> tuple[list[dict], dict]:
    """`lost run --survey` on the pings with the served runs' settings and ``--usbl-fixes fixes_path``: track.csv's rows, the summary."""
    import csv

    arguments = ["run", "--survey", str(pings_path), "--bathy", str(map_path), "--record-s", "5", "--window-s", "20", "--patch-centre",
                 "soundings", "--start-offset", "30,-20", "--dr-bias", "0.1,0.05", "--estimator", "all", "--usbl-fixes", str(fixes_path),
                 "--out", str(out)]
    assert main(arguments) == 0
    with open(out / "track.csv") as stream:
        return list(csv.DictReader(stream)), json.loads((out / "summary.json").read_text())


@pytest.fixture(scope="module")
def usbl_tow(tmp_path_factory):
    """Two minutes of the deep USBL tow (fixes every 2 s, some lost): scenario file, map, the simulator's records, the ping CRS."""
    from lost.host.io import write_npz
    from lost.host.io.simulated import simulated_pings
    from lost.host.scenario import builtin_scenario_path, load_scenario, simulate

    folder = tmp_path_factory.mktemp("usbl_tow")
    path = folder / "usbl_tow.toml"
    path.write_text(builtin_scenario_path("usbl_nav").read_text().replace("duration_s = 1800", "duration_s = 120"))
    scenario = load_scenario(path)
    grid, crs, _ = simulated_pings(scenario)
    return path, write_npz(grid, folder / "map.npz"), simulate(scenario)[1], crs


@pytest.fixture
def serve_replay():
    """``serve_replay(tow, tmp_path, replay_options=(), junk=(), two_ports=False, **settings)``: see :func:`_serve_replay`."""
    return _serve_replay
