"""Sensors on serial ports (a pty pair for the hardware): PD6 and NMEA lines written into the port reach the decoder and the
navigation as the UDP path's do; a port that goes away is counted and opened again, never a stop."""

from __future__ import annotations

import json
import os
import termios
import threading
import time
import tty

import numpy as np
import pytest

from lost.host.io import write_npz
from lost.host.io.simulated import EPOCH_S, simulated_pings
from lost.host.live.nmea import fix_sentences
from lost.host.live.receiver import LiveDecoder, UdpReceiver
from lost.host.live.serial import SerialSettings
from lost.host.live.stream import live_datagrams, vehicle_datagrams
from lost.host.scenario import builtin_scenario_path, load_scenario, simulate


@pytest.fixture(scope="module")
def dvl_tow(tmp_path_factory):
    """120 s of the short tow with a DVL: the scenario file, its map, and its PD6 datagrams as `lost replay` sends them."""
    folder = tmp_path_factory.mktemp("dvl_tow")
    text = builtin_scenario_path("short_exact_map").read_text().replace("has_velocity_sensor = false", "has_velocity_sensor = true")
    path = folder / "dvl_tow.toml"
    path.write_text(text.replace("duration_s = 600", "duration_s = 120"))
    scenario = load_scenario(path)
    grid, crs, _ = simulated_pings(scenario)
    pd6 = [d.payload for d in vehicle_datagrams(simulate(scenario)[1], crs, dvl_format="pd6", epoch_s=EPOCH_S)]
    return path, write_npz(grid, folder / "map.npz"), pd6


def _pty() -> tuple[int, str]:
    master, slave = os.openpty()
    name = os.ttyname(slave)
    tty.setraw(slave)
    os.close(slave)  # the reader opens it by name, as a device
    return master, name


def _wait_configured(master: int, timeout_s: float = 20.0) -> None:
    """Until pyserial has opened the pty's slave (its termios set raw: no echo), and flushed its input."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if termios.tcgetattr(master)[3] & termios.ECHO == 0 and termios.tcgetattr(master)[4] == termios.B9600:
            time.sleep(0.3)
            return
        time.sleep(0.02)
    raise AssertionError("the serial reader did not open the pty")


def _write_in_pieces(master: int, data: bytes, rng: np.random.Generator) -> None:
    """The bytes in pieces of 1 to 60 bytes: lines cut anywhere, as a serial line delivers them."""
    at = 0
    while at < len(data):
        step = int(rng.integers(1, 61))
        at += os.write(master, data[at:at + step])


def _values(receiver: UdpReceiver, write, until, timeout_s: float = 20.0) -> list:
    values: list = []
    thread = threading.Thread(target=receiver.run, args=(values.append,))
    thread.start()
    try:
        write()
        deadline = time.monotonic() + timeout_s
        while not until(receiver.decoder.counts) and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        receiver.stop()
        thread.join(10)
    return values


def test_pd6_and_nmea_lines_from_serial_ports_decode_as_the_same_lines_over_udp(dvl_tow):
    """A DVL (PD6) and a GNSS (NMEA) on two ptys, their bytes cut anywhere, plus noise: the values and counters of the UDP path."""
    _, _, pd6 = dvl_tow
    nmea = [(s + "\r\n").encode() for t in range(30) for s in fix_sentences(EPOCH_S + t, 0.01 + 1e-5 * t, 0.02, heading_deg=10.0 + t)]
    dvl_master, dvl_port = _pty()
    gnss_master, gnss_port = _pty()
    receiver = UdpReceiver(serial=(SerialSettings(dvl_port, "pd6"), SerialSettings(gnss_port, "nmea", baud=9600)))
    rng = np.random.default_rng(5)

    def write():
        _wait_configured(dvl_master)
        _wait_configured(gnss_master)
        _write_in_pieces(gnss_master, b"".join(nmea) + b"garbage on the line\r\n", rng)
        _write_in_pieces(dvl_master, b"".join(pd6) + b"$GPGGA,on the DVL's port\r\n", rng)

    values = _values(receiver, write, lambda c: c["PD6 :TS lines"] == len(pd6) and c["NMEA GGA sentences"] == 30)
    os.close(dvl_master)
    os.close(gnss_master)
    udp = LiveDecoder()
    expected = [v for payload in nmea + pd6 for v in udp.feed(payload)] + udp.finish()
    assert sorted(map(repr, values)) == sorted(map(repr, expected)) and len(values) > 250
    counts = receiver.decoder.counts
    for reason, n in udp.counts.items():
        assert counts[reason] == n, reason
    assert counts[f"serial {dvl_port}: line not of the port's kind pd6 (skipped)"] == 1
    assert counts[f"serial {gnss_port}: line not of the port's kind nmea (skipped)"] == 1
    assert counts[f"serial {dvl_port}: lines"] == sum(p.count(b"\n") for p in pd6)


def test_a_serial_port_that_goes_away_is_counted_and_opened_again(tmp_path):
    """The DVL's USB adapter unplugged (its pty closed) and plugged back (a new pty behind the same by-id link): lines of both."""
    link = tmp_path / "usb-dvl"
    first, name = _pty()
    link.symlink_to(name)
    receiver = UdpReceiver(serial=(SerialSettings(str(link), "json", retry_s=0.1),))
    lines = [json.dumps({"kind": "depth", "time_utc_s": EPOCH_S + k, "depth_m": 700.0 + k}).encode() + b"\n" for k in range(6)]
    second = None

    def write():
        nonlocal second
        _wait_configured(first)
        os.write(first, b"".join(lines[:3]) + b'{"kind": "depth", "time_')  # a line cut by the unplugging
        time.sleep(0.3)
        os.close(first)
        second, again = _pty()
        link.unlink()
        link.symlink_to(again)
        _wait_configured(second)
        os.write(second, b"".join(lines[3:]))

    values = _values(receiver, write, lambda c: c["JSON depth lines"] == 6)
    os.close(second)
    counts = receiver.decoder.counts
    assert [v.depth_m for v in values] == [700.0 + k for k in range(6)]
    assert counts[f"serial {link}: port lost (OSError; opened again; its lines lost meanwhile)"] == 1
    assert counts[f"serial {link}: part-line cut by the port's loss (skipped)"] == 1
    assert counts[f"serial {link}: port opened"] == 2


def test_a_dvl_on_a_serial_port_steers_the_served_records_as_over_udp(dvl_tow, serve_replay, tmp_path, capsys):
    """`lost serve` with its DVL on a pty (PD6) and the pings over UDP: the records the in-process UDP path makes of the same bytes."""
    from lost.host.cli.common import map_uncertainty
    from lost.host.io import read_grid
    from lost.host.io.survey_records import SurveyRecorder
    from lost.host.live.navigator import LiveNavigator
    from lost.host.nav import NavParameters

    path, map_path, pd6 = dvl_tow
    master, port = _pty()

    def write_dvl():
        _wait_configured(master)
        _write_in_pieces(master, b"".join(pd6), np.random.default_rng(2))
        time.sleep(1.0)  # read and queued before the pings come

    try:
        out, _ = serve_replay((path, map_path), tmp_path, ["--dvl", "none"], estimators=["pmf"], before_replay=write_dvl,
                              serial=[{"port": port, "kind": "pd6", "baud": 9600}])
    finally:
        os.close(master)
    replayed = capsys.readouterr()
    assert f"serial {port} (pd6, 9600 baud)" in replayed.out
    served = [json.loads(line)["estimates"]["pmf"] for line in (out / "log.jsonl").read_text().splitlines()]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["received"]["PD6 :TS lines"] == len(pd6) == 120

    params = NavParameters()
    grid, _ = map_uncertainty(read_grid(map_path), params)
    live = LiveNavigator(grid, params, ("pmf",), SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=5.0, window_s=20.0,
                                                                dr_bias_mps=(0.1, 0.05), start_offset_m=(30.0, -20.0), patch_centre="soundings"))
    decoder, expected = LiveDecoder(), []
    for value in (v for payload in pd6 for v in decoder.feed(payload)):
        live.add_sensor(value)
    for datagram in live_datagrams(simulated_pings(load_scenario(path))[2]):
        expected += [e for value in decoder.feed(datagram.payload) if hasattr(value, "beams") for e in live.add(value)]
    expected += live.finish()
    assert [e["velocity_source"] for e in served] == ["positions"] + ["dvl"] * 23
    assert len(served) == len(expected) == 24
    for mine, theirs in zip(served, expected, strict=True):
        assert mine == {k: v for k, v in theirs.as_dict().items() if k not in ("record", "time_utc_s", "t_s", "estimator")}
