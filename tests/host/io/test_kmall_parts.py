"""A .kmall file whose MRZ are split into partitions reads as the same file unsplit (lost.host.io.kmall_parts).

The splitting is the K-Controller's (``split_datagram``: header, partition, a slice of the body, closing length);
the files split are a real EM2040 .kmall of ../shared/data/real_survey and one written by ``write_kmall_pings``.
"""

from __future__ import annotations

from collections import Counter
from itertools import islice
from pathlib import Path

import numpy as np
import pytest

from lost.host.io.kmall_parts import REASONS, MrzJoiner, join_mrz_parts
from lost.host.io.kmall_write import split_datagram, write_kmall_pings
from lost.host.io.survey import Ping, open_survey

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
KMALL = REAL / "kongsberg_snippets_tmtgp" / "kmall_OS02_-2962169266352575506.kmall"
GA = REAL / "ga4430_em122_all" / "0243_P007_MBES_EM122_20150207_044356_Supporter_GA4430.all"


def kmall_datagrams(data: bytes) -> list[bytes]:
    """The datagrams of a whole .kmall file, by their length fields."""
    out, at = [], 0
    while at < len(data):
        size = int.from_bytes(data[at:at + 4], "little")
        out.append(data[at:at + size])
        at += size
    return out


def resplit(data: bytes, max_bytes: int, arrange=lambda parts: parts) -> tuple[bytes, int]:
    """The file with each MRZ split into parts of at most ``max_bytes`` (``arrange`` orders each ping's parts);
    returns it and the number of MRZ split."""
    out, split = [], 0
    for datagram in kmall_datagrams(data):
        if datagram[4:8] == b"#MRZ":
            parts = split_datagram(datagram, max_bytes)
            split += len(parts) > 1
            out += arrange(parts)
        else:
            out.append(datagram)
    return b"".join(out), split


def assert_identical(a: list[Ping], b: list[Ping]) -> None:
    """Every field equal, every beam equal (NaN where NaN)."""
    assert len(a) == len(b) > 0
    for x, y in zip(a, b, strict=True):
        for name, value in vars(x).items():
            other = getattr(y, name)
            if isinstance(value, np.ndarray):
                np.testing.assert_array_equal(other, value, err_msg=name)
            else:
                assert other == value or (value != value and other != other), name


@pytest.fixture(scope="module")
def real_kmall() -> bytes:
    if not KMALL.exists():
        pytest.skip(f"real survey file not at {KMALL}")
    return KMALL.read_bytes()


@pytest.mark.parametrize("order", ["in order", "parts reversed"])
def test_a_real_kmall_resplit_into_partitions_reads_as_the_original(real_kmall, tmp_path, order):
    arrange = (lambda parts: parts) if order == "in order" else (lambda parts: parts[::-1])
    data, split = resplit(real_kmall, 4000, arrange)
    path = tmp_path / "split.kmall"
    path.write_bytes(data)
    whole = open_survey(KMALL)
    original = list(whole)
    survey = open_survey(path)
    read = list(survey)
    assert split == len(original)  # every MRZ of the file split, none left whole
    assert_identical(original, read)
    assert not survey.skipped
    assert survey.notes[f"split.kmall: {REASONS['joined']}"] == split


def test_a_written_kmall_resplit_reads_as_written(tmp_path):
    if not GA.exists():
        pytest.skip(f"real survey file not at {GA}")
    written = write_kmall_pings(list(islice(open_survey(GA), 6)), tmp_path / "written.kmall")
    data, split = resplit(written.read_bytes(), 1500)
    path = tmp_path / "split.kmall"
    path.write_bytes(data)
    assert split == 6
    assert_identical(list(open_survey(written)), list(open_survey(path)))


def test_a_ping_missing_a_part_is_dropped_counted_and_the_others_read(real_kmall, tmp_path):
    dropped_one = {"done": False}

    def lose_the_second_part_once(parts):
        if dropped_one["done"]:
            return parts
        dropped_one["done"] = True
        return parts[:1] + parts[2:]

    data, split = resplit(real_kmall, 4000, lose_the_second_part_once)
    path = tmp_path / "lost_part.kmall"
    path.write_bytes(data)
    survey = open_survey(path)
    read = list(survey)
    original = list(open_survey(KMALL))
    assert_identical(original[1:], read)
    assert survey.skipped[f"lost_part.kmall: {REASONS['lost']}"] == 1


def _part(system: int, sec: int, count: int, number: int, label: bytes) -> bytes:
    body = label * 4  # the shortest MRZ part has 8 bytes after its partition
    size = 24 + len(body) + 4
    head = size.to_bytes(4, "little") + b"#MRZ" + bytes([0, system]) + (2040).to_bytes(2, "little")
    return head + sec.to_bytes(4, "little") + (0).to_bytes(4, "little") + count.to_bytes(2, "little") + number.to_bytes(2, "little") \
        + body + size.to_bytes(4, "little")


def test_the_joiner_holds_a_few_pings_drops_the_oldest_and_counts_each_outcome():
    joiner = MrzJoiner(Counter(), pending=2)
    assert joiner.add(_part(0, 1, 2, 1, b"a1")) is None
    assert joiner.add(_part(0, 2, 2, 1, b"b1")) is None
    assert joiner.add(_part(0, 3, 2, 1, b"c1")) is None  # three pending: the first (time 1) dropped
    assert joiner.counts[REASONS["lost"]] == 1
    joined = joiner.add(_part(0, 2, 2, 2, b"b2"))
    assert joined == join_mrz_parts([_part(0, 2, 2, 1, b"b1"), _part(0, 2, 2, 2, b"b2")])
    assert joined[20:24] == (1).to_bytes(2, "little") * 2 and joined[24:-4] == b"b1" * 4 + b"b2" * 4
    assert int.from_bytes(joined[:4], "little") == len(joined) == int.from_bytes(joined[-4:], "little")
    assert joiner.add(_part(0, 1, 2, 2, b"a2")) is None  # its first part is gone: it waits
    assert joiner.add(_part(0, 3, 2, 1, b"c1")) is None  # part 1 of time 3 twice: two pings of one time
    assert joiner.counts[REASONS["same_time"]] == 1
    assert joiner.add(_part(0, 4, 2, 3, b"x")) is None and joiner.counts[REASONS["bad_number"]] == 1
    assert joiner.add(_part(0, 5, 1, 1, b"whole")) == _part(0, 5, 1, 1, b"whole")
    assert joiner.finish() == 1  # time 1's second part, waiting
    assert joiner.counts[REASONS["lost"]] == 2 and joiner.counts[REASONS["joined"]] == 1
