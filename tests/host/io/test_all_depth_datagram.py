"""The older .all depth datagram 'D' (EM 120/300/1002/3000 era), read by lost.host.io.kongsberg_all.

No real 'D' file is at hand: the values come from the real XYZ88 pings of the GA-4430 EM122 .all (read and
checked against an independent parser's figures elsewhere), re-expressed here as 'D' datagrams by the
format's own scaling (Kongsberg's EM Series datagram formats: a 12-byte head and 16 bytes per beam, depths and
distances in whole resolution steps of centimetres), encoded with struct, not with the reader's dtypes. The
file's position and attitude datagrams are kept as they are.
"""

from __future__ import annotations

import math
import struct
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from lost.host.io.kongsberg_all import read_all_pings
from lost.host.io.survey_summary import summarize_survey

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
GA = REAL / "ga4430_em122_all" / "0243_P007_MBES_EM122_20150207_044356_Supporter_GA4430.all"
pytestmark = pytest.mark.skipif(not GA.is_file(), reason=f"the real survey file is not at {GA}")
EVERY = 2  # every other beam: a 'D' datagram holds at most 255 beams, the EM122 pings have 432


def frames(data: bytes) -> list[bytes]:
    """Each datagram of a whole .all file, with its length field."""
    out, at = [], 0
    while at < len(data):
        length = int.from_bytes(data[at:at + 4], "little")
        out.append(data[at:at + 4 + length])
        at += 4 + length
    return out


def depth_datagram(x_frame: bytes, ping, *, model: int | None = None, multiplier: int = 0, raw_depths: list[int] | None = None) -> bytes:
    """The 'D' datagram of one ping, by the format: the X datagram's header (type 'D'), then the ping's values scaled."""
    chosen = np.arange(0, ping.beams, EVERY)
    chosen = chosen[ping.valid[chosen]]  # a 'D' datagram holds the valid beams, by number
    origin = ping.origin_depth_m
    z = ping.depth_m[chosen] - origin
    z_res = math.ceil(np.max(np.abs(z)) * 100 / 32767)  # cm per step, so that every depth fits a signed 16-bit word
    xy = np.concatenate([ping.along_m[chosen], ping.across_m[chosen]])
    xy_res = math.ceil(np.max(np.abs(xy)) * 100 / 32767)
    head = struct.pack("<HHHBBBBH", round(ping.heading_deg * 100) % 36000, round(ping.sound_speed_mps * 10), round(origin * 100),
                       len(np.arange(0, ping.beams, EVERY)), len(chosen), z_res, xy_res, 0)
    depths = raw_depths if raw_depths is not None else [round(v * 100 / z_res) for v in z]
    beams = b"".join(
        struct.pack("<hhhhHHBBbB", depths[k] if depths[k] < 32768 else depths[k] - 65536, round(ping.across_m[b] * 100 / xy_res),
                    round(ping.along_m[b] * 100 / xy_res), 0, 0, 0, 0, 0, 0, b // EVERY + 1)
        for k, b in enumerate(chosen))
    header = bytearray(x_frame[:20])
    header[5] = ord("D")
    if model is not None:
        header[6:8] = model.to_bytes(2, "little")
    body = bytes(header[4:]) + head + beams + struct.pack("<b", multiplier)
    header[0:4] = (len(body) + 3).to_bytes(4, "little")
    framed = bytes(header[:4]) + body
    checksum = sum(framed[5:]) & 0xFFFF
    return framed + b"\x03" + checksum.to_bytes(2, "little")


def as_depth_file(tmp_path: Path, name: str = "depth.all", **kw) -> tuple[Path, list, list]:
    """The GA file with each XYZ88 datagram replaced by its 'D' datagram; the path, the X pings, the scaling used."""
    x_pings = list(read_all_pings(GA, Counter(), Counter()))
    out, k = [], 0
    for frame in frames(GA.read_bytes()):
        if frame[5] == ord("X"):
            out.append(depth_datagram(frame, x_pings[k], **kw))
            k += 1
        else:
            out.append(frame)
    assert k == len(x_pings) == 11
    path = tmp_path / name
    path.write_bytes(b"".join(out))
    return path, x_pings


def test_real_xyz88_pings_re_expressed_as_depth_datagrams_read_back_to_the_formats_resolution(tmp_path):
    path, x_pings = as_depth_file(tmp_path)
    skipped, notes = Counter(), Counter()
    d_pings = list(read_all_pings(path, skipped, notes))
    assert not skipped and len(d_pings) == len(x_pings)
    for x, d in zip(x_pings, d_pings, strict=True):
        chosen = np.arange(0, x.beams, EVERY)
        chosen = chosen[x.valid[chosen]]
        assert (d.time_s, d.lat_deg, d.lon_deg, d.head) == (x.time_s, x.lat_deg, x.lon_deg, x.head)  # the same P datagrams, the same header
        np.testing.assert_array_equal([d.roll_deg, d.pitch_deg, d.heave_m], [x.roll_deg, x.pitch_deg, x.heave_m])
        assert d.heading_deg == pytest.approx(x.heading_deg, abs=0.005)
        assert d.sound_speed_mps == pytest.approx(x.sound_speed_mps, abs=0.05)
        assert d.origin_depth_m == pytest.approx(x.origin_depth_m, abs=0.005)
        assert d.beams == chosen.size and d.valid.all()
        z_res = math.ceil(np.max(np.abs(x.depth_m[chosen] - x.origin_depth_m)) * 100 / 32767) / 100
        np.testing.assert_allclose(d.depth_m, x.depth_m[chosen], atol=z_res / 2 + 0.005 + 1e-9)
        assert z_res >= 0.11  # 3,600 m in a signed word: a step of 11 cm or more, so the check above is of the scaling
        xy_res = math.ceil(max(np.max(np.abs(x.along_m[chosen])), np.max(np.abs(x.across_m[chosen]))) * 100 / 32767) / 100
        np.testing.assert_allclose(d.across_m, x.across_m[chosen], atol=xy_res / 2 + 1e-9)
        np.testing.assert_allclose(d.along_m, x.along_m[chosen], atol=xy_res / 2 + 1e-9)
    summary = summarize_survey(path)
    assert summary["pings"] == 11 and 3480 - 0.2 <= summary["depth_m"]["min"] <= summary["depth_m"]["max"] <= 3661 + 0.2, summary


@pytest.mark.parametrize(("model", "multiplier", "raw", "depth_step_count", "extra_m"), [
    (300, 0, 40000, 40000, 0.0),       # EM 300: unsigned depths
    (1002, 0, 40000, 40000 - 65536, 0.0),  # others: signed
    (1002, 1, 100, 100, 655.36),       # the transducer depth offset multiplier adds 655.36 m
    (3000, 1, 100, 100, 0.0),          # EM 3000 left the multiplier undefined: not used
])
def test_the_depth_word_and_the_offset_multiplier_follow_the_model(tmp_path, model, multiplier, raw, depth_step_count, extra_m):
    x_first = next(read_all_pings(GA, Counter(), Counter()))
    count = int(x_first.valid[::EVERY].sum())
    raws = [raw] + [0] + [100] * (count - 2)  # the second beam of depth 0: no sounding
    path, x_pings = as_depth_file(tmp_path, model=model, multiplier=multiplier, raw_depths=raws)
    d = next(read_all_pings(path, Counter(), Counter()))
    z_res = math.ceil(np.max(np.abs(x_first.depth_m[::EVERY][x_first.valid[::EVERY]] - x_first.origin_depth_m)) * 100 / 32767) / 100
    origin = round(x_first.origin_depth_m * 100) / 100 + extra_m
    assert d.origin_depth_m == pytest.approx(origin, abs=1e-9)
    assert d.depth_m[0] == pytest.approx(depth_step_count * z_res + origin, abs=1e-9)
    assert list(d.valid[:3]) == [True, False, True]


def test_a_depth_datagram_holding_fewer_beams_than_it_says_is_skipped_and_counted(tmp_path):
    path, _ = as_depth_file(tmp_path)
    out = []
    for frame in frames(path.read_bytes()):
        if frame[5] == ord("D") and not any(f[5] == ord("D") for f in out):
            data = bytearray(frame)
            data[20 + 6] = data[20 + 7] = 255  # more beams than the datagram holds; the checksum made right again
            data[-2:] = (sum(data[5:-3]) & 0xFFFF).to_bytes(2, "little")
            frame = bytes(data)
        out.append(frame)
    path.write_bytes(b"".join(out))
    skipped = Counter()
    assert len(list(read_all_pings(path, skipped, Counter()))) == 10
    assert skipped[f"{path.name}: depth datagram 'D' holding fewer beams than it says"] == 1
