"""`lost serve` on bad settings and bad datagrams: a refused setting names itself before anything is written; a map without a
CRS, a port in use and a missing map are named errors; bytes that are no datagram never stop the decoding."""

from __future__ import annotations

import socket
from collections import Counter

import numpy as np
import pytest

from lost.host.cli import main
from lost.host.grid import Grid
from lost.host.io import write_npz
from lost.host.live.inputs import DvlVelocity, JsonInputDecoder
from lost.host.live.receiver import LiveDecoder


@pytest.fixture
def map_path(tmp_path):
    return write_npz(Grid(np.full((20, 20), 100.0), 0.0, 0.0, 10.0, "EPSG:32631"), tmp_path / "map.npz")


def _serve(tmp_path, text: str, capsys) -> tuple[int, str]:
    config = tmp_path / "live.toml"
    config.write_text(text)
    code = main(["serve", "--config", str(config), "--out", str(tmp_path / "out")])
    assert not (tmp_path / "out").exists()
    return code, capsys.readouterr().err


@pytest.mark.parametrize(("table", "named"), [
    ('listen = "127.0.0.1:0"\nbathy = "map.npz"\nrecrod_s = 2.0', "unknown field(s) ['recrod_s']"),
    ('listen = "127.0.0.1"\nbathy = "map.npz"', "[serve] listen must be HOST:PORT"),
    ('listen = "127.0.0.1:70000"\nbathy = "map.npz"', "[serve] listen must be HOST:PORT"),
    ('listen = "127.0.0.1:0"\nbathy = "map.npz"\nestimators = ["pmf", "ukf"]', "[serve] estimators must be some of"),
    ('listen = "127.0.0.1:0"\nbathy = "map.npz"\nestimators = []', "[serve] estimators must be some of"),
    ('listen = "127.0.0.1:0"\nbathy = "map.npz"\nrecord_s = -1.0', "serve.record_s (seconds)"),
    ('listen = "127.0.0.1:0"\nbathy = "map.npz"\nrecord_s = "5"', "serve.record_s (seconds)"),
    ('listen = "127.0.0.1:0"\nbathy = "map.npz"\noutputs = ["here"]', "[serve] outputs must be HOST:PORT"),
    ('listen = "127.0.0.1:0"\nbathy = "map.npz"\npatch_centre = "middle"', "[serve] patch_centre must be one of"),
    ('listen = "127.0.0.1:0"', "bathy"),
    ('listen = "127.0.0.1:0"\nbathy = "map.npz"\nreorder_lag_s = -0.5', "serve.reorder_lag_s"),
    ('listen = ["127.0.0.1:4001", "127.0.0.1:4001"]\nbathy = "map.npz"', "[serve] listen must be HOST:PORT or a list of them, each once"),
    ('listen = []\nbathy = "map.npz"', "[serve] listen must be HOST:PORT or a list of them, each once"),
    ('listen = ["127.0.0.1:4001", "here"]\nbathy = "map.npz"', "[serve] listen must be HOST:PORT"),
    ('listen = "127.0.0.1:0"\nbathy = "map.npz"\nusbl_default_sigma_m = 0.0', "serve.usbl_default_sigma_m"),
    ('listen = "127.0.0.1:0"\nbathy = "map.npz"\nusbl_default_sigma_m = "5"', "serve.usbl_default_sigma_m"),
    ('listen = "127.0.0.1:0"\nbathy = "map.npz"\nqueue_max_values = 0', "serve.queue_max_values"),
    ('listen = "127.0.0.1:0"\nbathy = "map.npz"\nqueue_max_values = 100.5', "serve.queue_max_values"),
])
def test_a_refused_setting_is_named_and_nothing_is_written(tmp_path, map_path, capsys, table, named):
    code, err = _serve(tmp_path, f"[serve]\n{table}\n", capsys)
    assert code == 1 and named in err and err.count("\n") == 1


def test_unknown_tables_no_serve_table_and_bad_navigation_are_named(tmp_path, map_path, capsys):
    code, err = _serve(tmp_path, '[serve]\nlisten = "127.0.0.1:0"\nbathy = "map.npz"\n[sevre]\n', capsys)
    assert code == 1 and "unknown table(s) ['sevre']" in err
    code, err = _serve(tmp_path, '[navigation]\n', capsys)
    assert code == 1 and "has no [serve] table" in err
    code, err = _serve(tmp_path, '[serve]\nlisten = "127.0.0.1:0"\nbathy = "map.npz"\n[navigation]\nno_such_parameter = 1\n', capsys)
    assert code == 1 and "no_such_parameter" in err


def test_a_missing_map_a_map_without_crs_and_a_port_in_use_are_named(tmp_path, map_path, capsys):
    code, err = _serve(tmp_path, '[serve]\nlisten = "127.0.0.1:0"\nbathy = "nowhere.npz"\n', capsys)
    assert code == 1 and "nowhere.npz" in err
    write_npz(Grid(np.full((20, 20), 100.0), 0.0, 0.0, 10.0, None), tmp_path / "bare.npz")
    code, err = _serve(tmp_path, '[serve]\nlisten = "127.0.0.1:0"\nbathy = "bare.npz"\n', capsys)
    assert code == 1 and "bare.npz has no CRS" in err
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        code, err = _serve(tmp_path, f'[serve]\nlisten = "127.0.0.1:{port}"\nbathy = "map.npz"\n', capsys)
    assert code == 1 and "in use" in err.lower()


@pytest.mark.parametrize("payload", [b"", b"\x00" * 3, b"$", b"\xff" * 2000, (12).to_bytes(4, "little") + b"#MRZ" + bytes(4),
                                     (64).to_bytes(4, "little") + b"#SKM" + bytes(52) + (64).to_bytes(4, "little"),
                                     (64).to_bytes(4, "little") + b"#MRZ" + bytes(52) + (64).to_bytes(4, "little")])
def test_bytes_that_are_no_datagram_are_counted_never_raised(payload):
    decoder = LiveDecoder()
    assert decoder.feed(payload) == []
    assert sum(decoder.counts.values()) >= 1


@pytest.mark.parametrize(("options", "named"), [(["--backend", "fpga"], "--backend fpga needs --port"),
                                                (["--port", "/dev/ttyUSB9"], "--port is for --backend fpga")])
def test_a_device_without_its_port_or_a_port_without_the_device_is_a_usage_error(tmp_path, map_path, capsys, options, named):
    config = tmp_path / "live.toml"
    config.write_text('[serve]\nlisten = "127.0.0.1:0"\nbathy = "map.npz"\n')
    assert main(["serve", "--config", str(config), "--out", str(tmp_path / "out"), *options]) == 2
    assert named in capsys.readouterr().err and not (tmp_path / "out").exists()


@pytest.mark.parametrize(("lines", "reason"), [
    ([":BE,+00100,+00200,+00000,A"], "PD6 :BE before any :TS (no time; skipped)"),
    ([":TS,26010100000000,35.0,+10.0, 100.0,1500.0,  0", ":BE,+00100,+00200,+00000,V"], "PD6 :BE marked bad (status V or -32768; skipped)"),
    ([":TS,26010100000000,35.0,+10.0, 100.0,1500.0,  0", ":BE,-32768,-32768,-32768,A"], "PD6 :BE marked bad (status V or -32768; skipped)"),
    ([":TS,2601010000,35.0,+10.0, 100.0,1500.0,  0"], "PD6 :TS line that does not parse (skipped)"),
    ([":TS,26013200000000,35.0,+10.0, 100.0,1500.0,  0"], "PD6 :TS line that does not parse (skipped)"),
    ([":TS,26010100000000,35.0,+10.0, 100.0,1500.0,  0", ":BE,+001.0,+00200,+00000,A"], "PD6 :BE line that does not parse (skipped)"),
    ([":XX,1,2,3"], "PD6 line of no PD6 kind (skipped)"),
])
def test_a_pd6_line_that_cannot_be_used_is_counted_never_raised(lines, reason):
    decoder = LiveDecoder()
    values = decoder.feed(("\r\n".join(lines) + "\r\n").encode())
    assert not any(isinstance(v, DvlVelocity) for v in values)
    assert decoder.counts[reason] == 1


def test_a_bad_json_line_is_counted_by_its_kind_never_raised():
    bad = ['{"kind": "dvl", "time_utc_s": 1.0, "east_mps": 0.1}', '{"kind": "dvl", "time_utc_s": 1.0, "east_mps": 0.1, "north_mps": "0"}',
           '{"kind": "depth", "time_utc_s": 1.0, "depth_m": 5.0, "extra": 1}', '{"kind": "depth", "time_utc_s": 1.0, "depth_m": NaN}',
           '{"kind": "gyro"}', "[1, 2]", "{not json"]
    counts = Counter()
    json_lines = JsonInputDecoder(counts)
    assert [v for line in bad for v in json_lines.feed(line)] == []
    assert counts["JSON dvl line with a missing, unknown or bad field (skipped)"] == 2
    assert counts["JSON depth line with a missing, unknown or bad field (skipped)"] == 2
    assert counts["JSON line of no known kind (skipped)"] == 2 and counts["JSON line that does not parse (skipped)"] == 1


@pytest.mark.parametrize(("serial", "named"), [
    ('[[serial]]\nport = "/dev/ttyUSB0"\nkind = "ais"', "[[serial]] kind must be one of ['nmea', 'pd6', 'json']"),
    ('[[serial]]\nport = "/dev/ttyUSB0"', "serial.0.kind"),
    ('[[serial]]\nport = "/dev/ttyUSB0"\nkind = "pd6"\nbaud = 0', "[[serial]] baud must be a serial line's rate"),
    ('[[serial]]\nport = "/dev/ttyUSB0"\nkind = "pd6"\nbaud = "9600"', "serial.0.baud"),
    ('[[serial]]\nport = "tcp://10.0.0.5:4001"\nkind = "nmea"', "pyserial knows no URL scheme 'tcp'"),
    ('[[serial]]\nport = ""\nkind = "nmea"', "[[serial]] port must be a device path or a pyserial URL"),
    ('[[serial]]\nport = "/dev/ttyUSB0"\nkind = "pd6"\nparity = "N"', "unknown field(s) ['parity']"),
    ('[[serial]]\nport = "/dev/ttyUSB0"\nkind = "pd6"\nretry_s = 0.0', "serial.0.retry_s (seconds)"),
    ('[[serial]]\nport = "/dev/ttyS0"\nkind = "pd6"\n[[serial]]\nport = "/dev/ttyS0"\nkind = "nmea"', "a serial port is named twice"),
    ('[serial]\nport = "/dev/ttyS0"\nkind = "pd6"', "serial ports are [[serial]] tables"),
])
def test_a_refused_serial_port_setting_is_named_and_nothing_is_written(tmp_path, map_path, capsys, serial, named):
    code, err = _serve(tmp_path, f'[serve]\nlisten = "127.0.0.1:0"\nbathy = "map.npz"\n{serial}\n', capsys)
    assert code == 1 and named in err and err.count("\n") == 1


def test_serial_noise_an_overlong_line_and_a_port_that_never_opens_are_counted_never_a_stop():
    """Bytes without line ends (a wrong baud rate) and a port that is not there: counted; the reader goes on."""
    import threading
    import time

    from lost.host.live.serial import MAX_LINE_BYTES, SerialReader, SerialSettings

    class Port:
        def __init__(self, chunks):
            self.chunks, self.in_waiting = list(chunks), 0

        def read(self, size):
            return self.chunks.pop(0) if self.chunks else time.sleep(0.01) or b""

        def close(self):
            pass

    counts, lines = Counter(), []
    chunks = [b"\xff\xfe" * MAX_LINE_BYTES, b"\x00" * 10, b"still the same line\r\n:TS,bad\r\n", b"\x80\x81\r\n", b":BE,+1,+2,+0,A\r\n"]
    tries = iter([OSError("no such device"), OSError("no such device"), Port(chunks)])

    def opener(settings):
        port = next(tries, None) or Port([])
        if isinstance(port, OSError):
            raise port
        return port

    reader = SerialReader(SerialSettings("/dev/ttyUSB9", "pd6", retry_s=0.01), lines.append, counts, opener=opener)
    thread = threading.Thread(target=reader.run)
    thread.start()
    time.sleep(0.5)
    reader.stop()
    thread.join(5)
    assert lines == [b":TS,bad\r\n", b":BE,+1,+2,+0,A\r\n"]
    assert counts["serial /dev/ttyUSB9: port did not open (tried again; its lines lost meanwhile)"] == 2
    assert counts[f"serial /dev/ttyUSB9: line longer than {MAX_LINE_BYTES} bytes (skipped)"] == 1
    assert counts["serial /dev/ttyUSB9: line not of the port's kind pd6 (skipped)"] == 1


def test_a_usbl_fix_without_a_covariance_is_refused_and_counted():
    import json
    from dataclasses import replace

    from lost.host.io.simulated import EPOCH_S
    from lost.host.live.inputs import UsblFix, json_input_line

    counts = Counter()
    decoder = JsonInputDecoder(counts)
    good = UsblFix(EPOCH_S, 0.01, 0.02, 700.0, 4.0, 9.0, 1.0)
    assert decoder.feed(json_input_line(good)) == [good]
    for sxx, syy, sxy in ((0.0, 9.0, 0.0), (-4.0, 9.0, 0.0), (4.0, 9.0, 6.0)):
        assert decoder.feed(json_input_line(replace(good, sxx_m2=sxx, syy_m2=syy, sxy_m2=sxy))) == []
    line = json.loads(json_input_line(good))
    del line["sxy_m2"]
    assert decoder.feed(json.dumps(line)) == []
    assert counts["JSON usbl line whose covariance is no covariance (skipped)"] == 3
    assert counts["JSON usbl line with a missing, unknown or bad field (skipped)"] == 1


def _nmea(body: str) -> bytes:
    checksum = 0
    for char in body:
        checksum ^= ord(char)
    return f"${body}*{checksum:02X}\r\n".encode()


@pytest.mark.parametrize(("body", "reason"), [
    ("PSONLLD,120000.00,1,V,10.0,20.0,700.0,3.0,2.0,0.0,,,,,", "USBL $PSONLLD marked not valid (status not A; skipped)"),
    ("PSONLLD,120000.00,1,A,north,20.0,700.0,3.0,2.0,0.0,,,,,", "USBL $PSONLLD with a field that is no number (skipped)"),
    ("PSONLLD,120000.00,1,A,10.0,20.0,nan,3.0,2.0,0.0,,,,,", "USBL $PSONLLD with a field that is no number (skipped)"),
    ("PSONLLD,250000.00,1,A,10.0,20.0,700.0,3.0,2.0,0.0,,,,,", "USBL $PSONLLD with a field that is no number (skipped)"),
    ("PSONLLD,125960.00,1,A,10.0,20.0,700.0,3.0,2.0,0.0,,,,,", "USBL $PSONLLD with a field that is no number (skipped)"),
    ("PSONLLD,1200005,1,A,10.0,20.0,700.0,3.0,2.0,0.0,,,,,", "USBL $PSONLLD with a field that is no number (skipped)"),
    ("PSONLLD,120000.00,1,A,10.0,20.0,700.0,-3.0,2.0,0.0,,,,,", "USBL $PSONLLD with a field that is no number (skipped)"),
    ("PSONLLD,120000.00,1,A,95.0,20.0,700.0,3.0,2.0,0.0,,,,,", "USBL $PSONLLD with a position off the globe (skipped)"),
    ("PSONLLD,120000.00", "USBL $PSONLLD with a field that is no number (skipped)"),
    ("PSONLLD,120000.00,1,A,10.0,20.0,700.0,,,,,,,,", "USBL $PSONLLD without error fields and no [serve] usbl_default_sigma_m (skipped)"),
    ("PSIMSSB,120000.00,B01,A,,U,E,M,500000.0,6000000.0,700.0,2.0,N,,", "USBL $PSIMSSB in coordinate system U (not geographic; skipped)"),
    ("PSIMSSB,120000.00,B01,A,,P,H,M,30.0,400.0,700.0,2.0,N,,", "USBL $PSIMSSB in coordinate system P (not geographic; skipped)"),
    ("PSIMSSB,120000.00,B01,V,E12,R,N,M,0.1,0.2,700.0,2.0,N,,", "USBL $PSIMSSB marked not valid (status not A; skipped)"),
    ("PSIMSSB,120000.00,B01,A,,R,N,M,0.1,0.2,700.0,0.0,N,,", "USBL $PSIMSSB without error fields and no [serve] usbl_default_sigma_m (skipped)"),
    ("PXYZ,1,2,3", "NMEA proprietary sentence (not used)"),
    ("HETHS,north,A", "NMEA THS sentence with a field that is no number"),
])
def test_a_usbl_sentence_that_cannot_be_used_is_counted_never_raised(body, reason):
    from lost.host.live.nmea import fix_sentences

    decoder = LiveDecoder()
    for sentence in fix_sentences(1767225600.0, 0.0, 0.0):
        decoder.feed(sentence.encode())
    assert decoder.feed(_nmea(body)) == [] and decoder.counts[reason] == 1
    assert decoder.feed(_nmea(body)[:-5] + b"\r\n") == []  # its checksum cut off
    assert decoder.counts["NMEA sentence with a wrong or missing checksum"] == 1


def test_a_usbl_sentence_before_any_zda_and_any_kmall_datagram_is_counted():
    decoder = LiveDecoder()
    assert decoder.feed(_nmea("PSONLLD,120000.00,1,A,10.0,20.0,700.0,3.0,2.0,0.0,,,,,")) == []
    assert decoder.counts["USBL $PSONLLD before any ZDA or .kmall datagram (no date; skipped)"] == 1
