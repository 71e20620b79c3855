"""Big-endian Kongsberg .all files: real pings re-written big-endian (tests/host/io/big_endian_all.py) read as the originals.

No real big-endian file is at hand (older processing units wrote them; none is published that could be used).
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from lost.host.io.all_frames import byte_order
from lost.host.io.kongsberg_all import read_all_pings
from lost.host.io.survey_summary import summarize_survey

from .big_endian_all import big_endian

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
FILES = [REAL / "ga4430_em122_all" / "0243_P007_MBES_EM122_20150207_044356_Supporter_GA4430.all",
         REAL / "kongsberg_snippets_tmtgp" / "0077_20221109_123655_Belgica.all",
         REAL / "kongsberg_snippets_tmtgp" / "all_a_y_-1333931979274893952.all"]
pytestmark = pytest.mark.skipif(not all(p.is_file() for p in FILES), reason=f"the real .all files are not under {REAL}")


def _pings(path: Path) -> tuple[list, Counter, Counter]:
    skipped, notes = Counter(), Counter()
    return list(read_all_pings(path, skipped, notes)), skipped, notes


@pytest.mark.parametrize("real", FILES, ids=lambda p: p.name[:24])
def test_real_pings_written_big_endian_read_back_value_for_value(real, tmp_path):
    path = tmp_path / real.name
    path.write_bytes(big_endian(real.read_bytes()))
    assert path.stat().st_size == real.stat().st_size and path.read_bytes() != real.read_bytes()
    assert byte_order(real) == "<" and byte_order(path) == ">"
    ours, skipped, notes = _pings(path)
    theirs, their_skipped, their_notes = _pings(real)
    assert len(ours) == len(theirs) > 0 and skipped == their_skipped
    for a, b in zip(ours, theirs, strict=True):
        for name, value in a.__dict__.items():
            np.testing.assert_array_equal(value, b.__dict__[name], err_msg=name)
    assert notes - their_notes == Counter({f"{path.name}: a big-endian .all file (as older processing units wrote them), read in that byte order": 1})


def test_a_big_endian_file_summarises_as_the_original(tmp_path):
    path = tmp_path / "ga.all"
    path.write_bytes(big_endian(FILES[0].read_bytes()))
    ours, theirs = summarize_survey(path), summarize_survey(FILES[0])
    for key in ("pings", "beams_per_ping", "valid_soundings", "time_start_utc", "time_end_utc", "depth_m", "extent"):
        assert ours[key] == theirs[key], key


@pytest.mark.parametrize("model", [300, 1002])  # EM 300's depth word unsigned, the others' signed
def test_depth_datagrams_written_big_endian_read_as_the_little_endian_ones(tmp_path, model):
    from .test_all_depth_datagram import as_depth_file

    x_first = next(read_all_pings(FILES[0], Counter(), Counter()))
    raws = [40000] + [100] * (int(x_first.valid[::2].sum()) - 1)  # a depth word above 32767: unsigned or negative by the model
    little, _ = as_depth_file(tmp_path, model=model, raw_depths=raws)
    big = tmp_path / "big.all"
    big.write_bytes(big_endian(little.read_bytes()))
    ours, theirs = _pings(big)[0], _pings(little)[0]
    assert len(ours) == len(theirs) == 11
    for a, b in zip(ours, theirs, strict=True):
        for name, value in a.__dict__.items():
            np.testing.assert_array_equal(value, b.__dict__[name], err_msg=name)
