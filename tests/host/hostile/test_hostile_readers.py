"""Hostile multibeam files: cut off, damaged, unknown, without positions, out of time order, all flagged, mixed.

Each is made from a real file's bytes (../shared/data/real_survey), so the damage is the only thing made here.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from lost.host.io.errors import NoPingsError, SurveyFileError
from lost.host.io.survey import open_survey
from lost.host.io.survey_grid import grid_survey
from lost.host.io.survey_summary import summarize_survey

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
pytestmark = pytest.mark.skipif(not REAL.is_dir(), reason=f"the real survey files are not at {REAL} (shared/data/real_survey beside the repository)")
GA = REAL / "ga4430_em122_all" / "0243_P007_MBES_EM122_20150207_044356_Supporter_GA4430.all"
GSF = REAL / "noaa_okeanos_ex1604_gsf" / "0029_20160323_185603_EX1604_MB.gsf"
KMALL = REAL / "kongsberg_snippets_tmtgp" / "kmall_OS02_-2962169266352575506.kmall"


def _datagrams(data: bytes) -> list[tuple[int, int, str]]:
    """(offset, total length, type) of each datagram of a whole .all file."""
    out, at = [], 0
    while at < len(data):
        length = int.from_bytes(data[at:at + 4], "little")
        out.append((at, length + 4, chr(data[at + 5])))
        at += length + 4
    return out


def _write(tmp_path: Path, name: str, data: bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(data)
    return path


def test_an_all_file_cut_inside_a_datagram_keeps_every_whole_ping_and_counts_the_cut(tmp_path):
    data = GA.read_bytes()
    last_x = [d for d in _datagrams(data) if d[2] == "X"][-1]
    path = _write(tmp_path, "cut.all", data[: last_x[0] + last_x[1] // 2])
    s = summarize_survey(path)
    assert s["pings"] == 10
    assert any("cut off by the end of the file" in reason for reason in s["skipped"])


def test_garbage_inside_an_all_file_is_skipped_counted_and_the_rest_read(tmp_path):
    data = GA.read_bytes()
    third_x = [d for d in _datagrams(data) if d[2] == "X"][2]
    junk = np.random.default_rng(5).integers(0, 256, 3000, dtype=np.uint8).tobytes().replace(b"\x02", b"\x01")
    path = _write(tmp_path, "junk.all", data[: third_x[0]] + junk + data[third_x[0]:])
    s = summarize_survey(path)
    assert s["pings"] == 11 and s["valid_soundings"] == summarize_survey(GA)["valid_soundings"]
    assert s["skipped"] == {"junk.all: bytes that are no datagram (damaged data, resynchronised)": 1}


def test_a_depth_datagram_with_a_wrong_checksum_is_skipped_and_counted(tmp_path):
    data = bytearray(GA.read_bytes())
    at, length, _ = [d for d in _datagrams(bytes(data)) if d[2] == "X"][4]
    data[at + 100] ^= 0xFF  # a beam's byte: the frame holds, the checksum does not
    s = summarize_survey(_write(tmp_path, "flipped.all", bytes(data)))
    assert s["pings"] == 10 and s["skipped"] == {"flipped.all: datagram 'X' with a wrong checksum": 1}


def test_pings_without_any_position_are_skipped_counted_and_nothing_is_gridded(tmp_path):
    data = GA.read_bytes()
    kept = b"".join(data[a:a + n] for a, n, t in _datagrams(data) if t != "P")
    path = _write(tmp_path, "nonav.all", kept)
    s = summarize_survey(path)
    assert s["pings"] == 0 and s["skipped"] == {"nonav.all: ping without a position at its time": 11}
    with pytest.raises(NoPingsError, match="no valid sounding to grid"):
        grid_survey(path, node_m=50.0)


def test_files_given_out_of_time_order_skip_the_earlier_pings_and_say_so(tmp_path):
    s = summarize_survey([REAL / "kongsberg_snippets_tmtgp" / "all_a_f_ALL_6516408039690331208.all", GA])  # 2015-05 then 2015-02
    assert s["pings"] == 9
    assert s["skipped"] == {f"{GA.name}: ping time going backwards (more than 1 s before a ping read earlier)": 11}
    s = summarize_survey([GA, REAL / "kongsberg_snippets_tmtgp" / "all_a_f_ALL_6516408039690331208.all"])
    assert s["pings"] == 20 and not s["skipped"]
    assert s["notes"]["all_a_f_ALL_6516408039690331208.all: pings of another sonar head or ship (serial 233) than the first file's"] == 1


def test_all_beams_flagged_counts_no_valid_sounding_and_gridding_refuses(tmp_path):
    data = bytearray(GA.read_bytes())
    for at, length, kind in _datagrams(bytes(data)):
        if kind != "X":
            continue
        beams = int.from_bytes(data[at + 28:at + 30], "little")
        for b in range(beams):
            data[at + 40 + 20 * b + 16] |= 0x80  # detection info bit 7: invalid
        body = np.frombuffer(bytes(data[at + 5:at + length - 3]), np.uint8)
        data[at + length - 2:at + length] = (int(body.sum()) & 0xFFFF).to_bytes(2, "little")
    path = _write(tmp_path, "flagged.all", bytes(data))
    s = summarize_survey(path)
    assert s["pings"] == 11 and s["valid_soundings"] == 0 and s["extent"] is None and s["depth_m"] is None
    with pytest.raises(NoPingsError, match="flagged.all: no valid sounding to grid"):
        grid_survey(path, node_m=50.0)


def test_files_of_different_formats_at_once_are_refused_by_name():
    with pytest.raises(SurveyFileError, match="different formats"):
        open_survey([GA, GSF])


def test_an_unknown_or_empty_file_is_named(tmp_path):
    with pytest.raises(SurveyFileError, match="short.all is 3 bytes long"):
        open_survey(_write(tmp_path, "short.all", b"abc"))
    with pytest.raises(SurveyFileError, match="zeros.gsf is not a Kongsberg .all, .kmall or GSF file"):
        open_survey(_write(tmp_path, "zeros.gsf", bytes(64)))
    with pytest.raises(FileNotFoundError, match="no survey file at"):
        open_survey(tmp_path / "absent.kmall")


def test_a_kmall_file_cut_inside_a_datagram_keeps_the_whole_pings_and_counts_the_cut(tmp_path):
    data = KMALL.read_bytes()
    whole = summarize_survey(KMALL)
    path = _write(tmp_path, "cut.kmall", data[: len(data) - 5000])
    s = summarize_survey(path)
    assert 0 < s["pings"] <= whole["pings"]
    assert [r for r in s["skipped"] if "cut off by the end of the file" in r]


def test_a_gsf_file_cut_inside_a_record_keeps_the_whole_pings_and_counts_the_cut(tmp_path):
    data = GSF.read_bytes()
    path = _write(tmp_path, "cut.gsf", data[: len(data) * 3 // 4])
    s = summarize_survey(path)
    assert 0 < s["pings"] < 8
    assert any("cut.gsf" in reason for reason in s["skipped"]), s


def test_garbage_inside_a_kmall_file_keeps_the_pings_before_it_and_counts_the_rest(tmp_path):
    data = KMALL.read_bytes()
    whole = summarize_survey(KMALL)
    middle = len(data) // 2
    at = data.index(b"#MRZ", middle) - 4  # the start of an MRZ past the middle
    s = summarize_survey(_write(tmp_path, "junk.kmall", data[:at] + b"\x00" * 64 + data[at:]))
    assert 0 < s["pings"] < whole["pings"]
    assert s["skipped"] == {"junk.kmall: bytes that are no datagram where one should start (the file's remainder not read)": 1}


def test_lost_grid_with_no_sounding_to_place_is_one_line_and_writes_nothing(tmp_path, capsys):
    from lost.host.cli import main

    data = GA.read_bytes()
    kept = b"".join(data[a:a + n] for a, n, t in _datagrams(data) if t != "P")  # no position: nothing can be placed
    path = _write(tmp_path, "nonav.all", kept)
    assert main(["grid", str(path), "--node-m", "50", "--out", str(tmp_path / "g.nc")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "lost grid: nonav.all: no valid sounding to grid" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["nonav.all"]


def test_a_kmall_file_ending_inside_a_split_ping_or_with_a_bad_part_number_counts_both_and_reads_the_rest(tmp_path):
    from lost.host.io.kmall_parts import REASONS
    from lost.host.io.kmall_write import split_datagram

    datagrams, at, data = [], 0, KMALL.read_bytes()
    while at < len(data):
        size = int.from_bytes(data[at:at + 4], "little")
        datagrams.append(data[at:at + size])
        at += size
    mrz = [k for k, d in enumerate(datagrams) if d[4:8] == b"#MRZ"]
    parts = {k: split_datagram(datagrams[k], 4000) for k in mrz}
    first, last = mrz[0], mrz[-1]
    bad = bytearray(parts[first][0])
    bad[22:24] = (len(parts[first]) + 1).to_bytes(2, "little")  # a part number beyond its count
    parts[first][0] = bytes(bad)
    parts[last] = parts[last][:-1]  # the file ends before the last ping's last part
    path = _write(tmp_path, "split.kmall", b"".join(b"".join(parts[k]) if k in parts else d for k, d in enumerate(datagrams)))
    s = summarize_survey(path)
    assert s["pings"] == len(mrz) - 2
    assert s["skipped"][f"split.kmall: {REASONS['bad_number']}"] == 1
    assert s["skipped"][f"split.kmall: {REASONS['lost']}"] == 2  # the first ping's other parts wait to the end, and the last


def test_a_big_endian_all_file_cut_and_damaged_keeps_its_whole_pings_and_counts_both(tmp_path):
    from ..io.big_endian_all import big_endian

    data = big_endian(GA.read_bytes())
    little = GA.read_bytes()
    third_x, last_x = [d for d in _datagrams(little) if d[2] == "X"][2], [d for d in _datagrams(little) if d[2] == "X"][-1]
    junk = np.random.default_rng(6).integers(0, 256, 3000, dtype=np.uint8).tobytes().replace(b"\x02", b"\x01")
    damaged = data[: third_x[0]] + junk + data[third_x[0]: last_x[0] + last_x[1] // 2]  # same offsets: re-written in place
    s = summarize_survey(_write(tmp_path, "big.all", damaged))
    assert s["pings"] == 10
    assert s["skipped"]["big.all: bytes that are no datagram (damaged data, resynchronised)"] == 1
    assert any("cut off by the end of the file" in reason for reason in s["skipped"])


def test_a_big_endian_all_file_damaged_at_its_start_is_still_read_in_its_order(tmp_path):
    from ..io.big_endian_all import big_endian

    junk = np.random.default_rng(7).integers(0, 256, 500, dtype=np.uint8).tobytes().replace(b"\x02", b"\x01")
    s = summarize_survey(_write(tmp_path, "big.all", b"\x07\x00\x00\x00\x02X" + junk + big_endian(GA.read_bytes())))
    assert s["pings"] == 11 and s["valid_soundings"] == summarize_survey(GA)["valid_soundings"]
    assert s["skipped"] == {"big.all: bytes that are no datagram (damaged data, resynchronised)": 1}


def test_garbage_inside_a_gsf_file_keeps_the_pings_before_it_and_counts_the_rest(tmp_path):
    data = GSF.read_bytes()
    at = len(data) // 2
    while int.from_bytes(data[at + 4:at + 8], "big") & 0x3FFFFF != 2 or int.from_bytes(data[at:at + 4], "big") > 1 << 20:
        at += 1  # the framing of a ping record past the middle
    s = summarize_survey(_write(tmp_path, "junk.gsf", data[:at] + b"\xff" * 64 + data[at:]))
    assert 0 < s["pings"] < 8
    assert s["skipped"] == {f"junk.gsf: bytes that are no GSF record at byte {at} (the file's remainder not read)": 1}
