"""`lost replay` through localhost UDP into the receiver: every ping arrives equal to the file's; faults counted on both sides.

And real pings (a dual-head EM2040 .all, with attitude) as live datagrams into the decoder, equal to the .kmall file's pings.
"""

from __future__ import annotations

import math
import threading
from itertools import islice
from pathlib import Path

import numpy as np
import pytest

from lost.host.cli import main
from lost.host.io.kmall_write import write_kmall_pings
from lost.host.io.simulated import simulated_pings
from lost.host.io.survey import Ping, open_survey
from lost.host.live.nmea import HeadingFix, PositionFix
from lost.host.live.receiver import LiveDecoder, UdpReceiver
from lost.host.live.stream import live_datagrams
from lost.host.scenario import builtin_scenario_path, load_scenario


@pytest.fixture(scope="module")
def tow(tmp_path_factory):
    """100 pings of the short tow as a .kmall file, and those pings as read from it (the file's)."""
    _, crs, pings = simulated_pings(load_scenario(builtin_scenario_path("short_exact_map")))
    path = write_kmall_pings(islice(pings, 100), tmp_path_factory.mktemp("tow") / "tow.kmall")
    return path, list(open_survey(path, crs=crs))


def _replayed(arguments: list[str]):
    receiver = UdpReceiver()
    values: list = []
    thread = threading.Thread(target=receiver.run, args=(values.append,))
    thread.start()
    try:
        code = main(["replay", *arguments, "--to", f"127.0.0.1:{receiver.address[1]}", "--speed", "0", "--max-datagram-bytes", "3000"])
    finally:
        receiver.stop()
        thread.join(10)
    assert code == 0
    return values, receiver.decoder.counts


def _assert_equal(received: Ping, filed: Ping) -> None:
    for name in ("time_s", "lat_deg", "lon_deg", "heading_deg", "roll_deg", "pitch_deg", "heave_m", "sound_speed_mps", "head", "origin_depth_m"):
        x, y = getattr(filed, name), getattr(received, name)
        assert (isinstance(x, float) and math.isnan(x) and math.isnan(y)) or x == y, name
    for name in ("along_m", "across_m", "depth_m", "valid"):
        np.testing.assert_array_equal(getattr(received, name), getattr(filed, name))


def test_a_replay_at_speed_0_arrives_ping_for_ping_equal_to_the_file(tow, capsys):
    path, filed = tow
    values, counts = _replayed([str(path)])
    pings = [v for v in values if isinstance(v, Ping)]
    assert len(pings) == len(filed) == 100
    for received, expected in zip(pings, filed, strict=True):
        _assert_equal(received, expected)
    assert counts["MRZ joined from parts"] == 100 and counts["kmall #MRZ parts"] == 300  # 8 kB MRZ in 3,000-byte parts
    fixes = [v for v in values if isinstance(v, PositionFix)]
    assert len(fixes) == 100 and sum(math.isfinite(f.speed_mps) for f in fixes) == 99  # the first has no ping before it
    for fix, ping in zip(fixes, filed, strict=True):
        assert fix.time_s == pytest.approx(ping.time_s, abs=1e-3)
        assert fix.lat_deg == pytest.approx(ping.lat_deg, abs=1e-8) and fix.lon_deg == pytest.approx(ping.lon_deg, abs=1e-8)
    headings = [v.heading_deg for v in values if isinstance(v, HeadingFix)]
    np.testing.assert_allclose(headings, [p.heading_deg for p in filed], atol=0.006)
    assert not [reason for reason, n in counts.items() if n and ("skipped" in reason or "lost" in reason or "wrong" in reason)]
    out = capsys.readouterr().out
    assert "sent 100 pings as 400 .kmall and 399 NMEA datagrams" in out  # SPO + 3 MRZ parts (no attitude: no SKM); no VTG first


def test_faults_are_drawn_counted_and_survived(tow, capsys):
    path, filed = tow
    values, counts = _replayed([str(path), "--loss", "0.05", "--reorder", "0.05", "--duplicate", "0.05", "--seed", "7"])
    out = capsys.readouterr().out
    line = next(text for text in out.splitlines() if text.startswith("faults (seed 7)"))
    total, lost, duplicated, reordered = (int(w) for w in line.split(":")[1].split("(")[0].replace(",", " ").split() if w.isdigit())
    assert total == 799 and lost > 20 and duplicated > 20 and reordered > 20
    pings = [v for v in values if isinstance(v, Ping)]
    by_time = {p.time_s: p for p in filed}
    for ping in pings:  # every ping that arrives is the file's, whatever came lost, twice or out of order
        _assert_equal(ping, by_time[ping.time_s])
    assert len({p.time_s for p in pings}) == len(pings)  # no ping twice
    assert len(pings) >= 100 - lost  # at most one ping lost per lost datagram
    # Both sides count: every duplicated .kmall datagram is skipped once; every ping not received is counted missing
    # (the first and last pings arrived here, so the ping counter's gaps are all the lost ones).
    drawn = line.split("(.kmall ")[1]
    kmall_lost, kmall_duplicated = (int(drawn.split(" lost")[0]), int(drawn.split(", ")[1].split(" duplicated")[0]))
    assert counts["duplicate kmall datagram (skipped)"] == kmall_duplicated > 0
    assert pings[0].time_s == filed[0].time_s and max(p.time_s for p in pings) == filed[-1].time_s
    assert counts["pings missing from the ping counter's sequence"] == 100 - len(pings) > 0
    assert counts["MRZ with parts lost (ping dropped)"] <= 100 - len(pings) <= kmall_lost


REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
DUAL_HEAD = REAL / "kongsberg_snippets_tmtgp" / "all_a_c_519880139284219668.all"


@pytest.mark.parametrize("max_bytes", [64_000, 8_000])
def test_real_pings_decode_equal_to_the_kmall_files(max_bytes, tmp_path):
    if not DUAL_HEAD.exists():
        pytest.skip(f"real survey file not at {DUAL_HEAD}")
    pings = list(open_survey(DUAL_HEAD))
    filed = list(open_survey(write_kmall_pings(pings, tmp_path / "x.kmall")))
    decoder = LiveDecoder()
    values = []
    for datagram in live_datagrams(pings, max_datagram_bytes=max_bytes):
        values += decoder.feed(datagram.payload)
    values += decoder.finish()
    received = [v for v in values if isinstance(v, Ping)]
    assert len(received) == len(filed) == 12 and {p.head for p in received} == {0, 1}  # two heads, pings of one time each
    for ping, expected in zip(received, filed, strict=True):
        _assert_equal(ping, expected)
    assert received[0].roll_deg == pytest.approx(pings[0].roll_deg, abs=1e-5)  # the #SKM sample (one per time, 5 times) reached the ping
    assert decoder.counts["MRZ joined from parts"] == (12 if max_bytes == 8_000 else 0)
    assert decoder.counts["kmall #SKM datagrams"] == 5 and not decoder.counts["ping without attitude at its time (its #SKM late or lost)"]
