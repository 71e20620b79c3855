"""Hostile live input: malformed datagrams and sentences into the receiver (each counted, never a stop); bad `lost replay` options."""

from __future__ import annotations

import struct
from itertools import islice

import pytest

from lost.host.cli import main
from lost.host.io.kmall_write import encode_mrz, encode_skm, split_datagram
from lost.host.io.simulated import simulated_pings
from lost.host.io.survey import Ping
from lost.host.live.nmea import fix_sentences
from lost.host.live.receiver import PENDING_PINGS, LiveDecoder
from lost.host.scenario import builtin_scenario_path, load_scenario


@pytest.fixture(scope="module")
def pings():
    _, _, stream = simulated_pings(load_scenario(builtin_scenario_path("short_exact_map")))
    return list(islice(stream, 12))


def _after(decoder: LiveDecoder, bad: bytes, good: bytes) -> list:
    """The bad datagram is taken without raising, and a good one after it still decodes."""
    assert decoder.feed(bad) == []
    return decoder.feed(good)


def _resized(datagram: bytes, body: bytes) -> bytes:
    size = len(datagram[:-4][:24]) + len(body) + 4
    return size.to_bytes(4, "little") + datagram[4:24] + body + size.to_bytes(4, "little")


@pytest.mark.parametrize("bad, reason", [
    (b"\x00\x01garbage that is no datagram", "datagram of neither .kmall, NMEA, PD6 nor JSON (skipped)"),
    (b"", "datagram of neither .kmall, NMEA, PD6 nor JSON (skipped)"),
    ("length", "kmall #MRZ datagram whose length fields disagree with its size (skipped)"),
    ("cut", "kmall #MRZ that does not decode (error; skipped)"),
    ("sounding size", "kmall #MRZ that does not decode (ValueError; skipped)"),
    ("part zero", "kmall #MRZ with an impossible partition number (skipped)"),
    ("short", "kmall #MRZ datagram too short for its parts (skipped)"),
    ("skm", "kmall #SKM that does not decode (skipped)"),
])
def test_a_malformed_kmall_datagram_is_counted_and_skipped(pings, bad, reason):
    good = encode_mrz(pings[1], ping_count=1)
    mrz = encode_mrz(pings[0])
    if bad == "length":
        bad = mrz[:-8] + mrz[-4:]  # a datagram cut inside, its length fields as before
    elif bad == "cut":
        bad = _resized(mrz, mrz[24:200])  # lengths consistent, the body cut inside the ping info
    elif bad == "sounding size":
        at = 24 + 12 + 144 + 36 + 6  # numBytesPerSounding in the rx info
        bad = mrz[:at] + struct.pack("<H", 100) + mrz[at + 2:]
    elif bad == "part zero":
        bad = mrz[:20] + struct.pack("<HH", 2, 0) + mrz[24:]
    elif bad == "short":
        bad = _resized(mrz, b"")
    elif bad == "skm":
        skm = encode_skm(pings[0].time_s, roll_deg=1.0, pitch_deg=2.0, heave_m=0.1, heading_deg=10.0)
        bad = _resized(skm, skm[24:40])
    decoder = LiveDecoder()
    out = _after(decoder, bad, good)
    assert [p.time_s for p in out if isinstance(p, Ping)] == [pings[1].time_s]
    undecodable = reason.endswith("(error; skipped)")  # whichever error pykmall meets first in the cut body
    hits = [r for r, n in decoder.counts.items() if n and (r == reason or (undecodable and r.startswith("kmall #MRZ that does not decode")))]
    assert hits, dict(decoder.counts)


def test_lost_partitions_drop_their_ping_counted_and_the_rest_goes_on(pings):
    decoder = LiveDecoder()
    received = []
    for k, ping in enumerate(pings):
        parts = split_datagram(encode_mrz(ping, ping_count=k), 3000)
        for part in parts[:-1] if k in (2, 5) else parts:  # the last part of two pings lost
            received += decoder.feed(part)
    received += decoder.finish()
    assert len(received) == len(pings) - 2
    assert decoder.counts["MRZ with parts lost (ping dropped)"] == 2
    assert decoder.counts["pings missing from the ping counter's sequence"] == 2
    assert PENDING_PINGS >= 1


def test_parts_out_of_order_and_twice_join_once(pings):
    parts = split_datagram(encode_mrz(pings[0]), 2000)
    decoder = LiveDecoder()
    out = []
    for part in [parts[2], parts[0], parts[0], parts[3], parts[1], *parts[4:]]:
        out += decoder.feed(part)
    assert len(out) == 1 and decoder.counts["duplicate kmall datagram (skipped)"] == 1 and decoder.counts["MRZ joined from parts"] == 1


@pytest.mark.parametrize("mangle, reason", [
    (lambda s: s[:-2] + ("00" if s[-2:] != "00" else "11"), "NMEA sentence with a wrong or missing checksum"),
    (lambda s: s.split("*")[0], "NMEA sentence with a wrong or missing checksum"),
    (lambda s: "$GPGGA,not,a,sentence", "NMEA sentence with a wrong or missing checksum"),
    (lambda s: "$\xff\xfe", "NMEA sentence"),
])
def test_a_bad_nmea_sentence_is_counted_and_the_next_fix_still_comes(pings, mangle, reason):
    zda, gga, *_ = fix_sentences(pings[0].time_s, pings[0].lat_deg, pings[0].lon_deg, heading_deg=10.0)
    decoder = LiveDecoder()
    assert decoder.feed((zda + "\r\n").encode()) == []
    assert decoder.feed(mangle(gga).encode("latin-1")) == []
    decoder.feed((gga + "\r\n").encode())
    fixes = decoder.finish()
    assert len(fixes) == 1 and fixes[0].lat_deg == pytest.approx(pings[0].lat_deg, abs=1e-8)
    assert any(n and r.startswith(reason) for r, n in decoder.counts.items()), dict(decoder.counts)


def test_a_gga_before_any_zda_has_no_date_and_is_counted(pings):
    _, gga, *_ = fix_sentences(pings[0].time_s, pings[0].lat_deg, pings[0].lon_deg)
    decoder = LiveDecoder()
    assert decoder.feed(gga.encode()) == [] and decoder.finish() == []
    assert decoder.counts["NMEA GGA before any ZDA (no date)"] == 1


@pytest.mark.parametrize("options, message", [
    (["--to", "localhost"], "HOST:PORT"),
    (["--to", "127.0.0.1:70000"], "HOST:PORT"),
    (["--to", "127.0.0.1:9", "--loss", "1.5"], "probability"),
    (["--to", "127.0.0.1:9", "--reorder", "x"], "probability"),
    (["--to", "127.0.0.1:9", "--speed", "-1"], "--speed"),
    (["--to", "127.0.0.1:9", "--speed", "inf"], "--speed"),
    (["--to", "127.0.0.1:9", "--max-datagram-bytes", "70000"], "--max-datagram-bytes"),
    (["--to", "127.0.0.1:9", "--reorder-by", "0"], "--reorder-by"),
    (["--to", "127.0.0.1:9", "--reorder-by", "two"], "--reorder-by"),
    ([], "--to"),
])
def test_bad_replay_options_are_usage_errors(options, message, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["replay", "short", *options])
    assert exit_.value.code == 2 and message in capsys.readouterr().err


@pytest.mark.parametrize("source, message", [("absent.all", "no survey file or scenario at absent.all"), ("nosuch", "no built-in scenario 'nosuch'")])
def test_a_source_that_is_not_there_is_named(source, message, capsys):
    assert main(["replay", source, "--to", "127.0.0.1:9"]) == 1
    assert message in capsys.readouterr().err


def test_a_file_of_no_survey_format_is_named(tmp_path, capsys):
    text = tmp_path / "notes.txt"
    text.write_text("not a survey at all, just some words in a file\n")
    assert main(["replay", str(text), "--to", "127.0.0.1:9"]) == 1
    assert "notes.txt is not a Kongsberg .all, .kmall or GSF file" in capsys.readouterr().err


def test_a_dvl_asked_of_a_survey_file_is_a_usage_error(tmp_path, pings, capsys):
    from lost.host.io.kmall_write import write_kmall_pings

    path = write_kmall_pings(pings[:2], tmp_path / "two.kmall")
    assert main(["replay", str(path), "--to", "127.0.0.1:9", "--dvl", "pd6"]) == 2
    assert "a survey file has no DVL to send" in capsys.readouterr().err


def test_usbl_fixes_asked_of_a_survey_file_or_of_a_scenario_without_a_usbl_are_usage_errors(tmp_path, pings, capsys):
    from lost.host.io.kmall_write import write_kmall_pings

    path = write_kmall_pings(pings, tmp_path / "tow.kmall")
    assert main(["replay", str(path), "--to", "127.0.0.1:9", "--usbl", "json"]) == 2
    assert "--usbl json: a survey file has no USBL fixes to send" in capsys.readouterr().err
    assert main(["replay", "short", "--to", "127.0.0.1:9", "--usbl", "json"]) == 2
    assert "--usbl json: scenario 'short' has no USBL" in capsys.readouterr().err
    for vendor in ("psonlld", "psimssb"):
        assert main(["replay", str(path), "--to", "127.0.0.1:9", "--usbl", vendor]) == 2
        assert f"--usbl {vendor}: a survey file has no USBL fixes to send" in capsys.readouterr().err
        assert main(["replay", "short", "--to", "127.0.0.1:9", "--usbl", vendor]) == 2
        assert f"--usbl {vendor}: scenario 'short' has no USBL" in capsys.readouterr().err
    with pytest.raises(SystemExit) as refused:  # no such layout: argparse's own usage error
        main(["replay", "short", "--to", "127.0.0.1:9", "--usbl", "ptsag"])
    assert refused.value.code == 2 and "invalid choice: 'ptsag'" in capsys.readouterr().err
