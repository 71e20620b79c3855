"""The .kmall SKM attitude samples read as NumPy arrays: pykmall's values bit for bit on every real file; the active sensor's."""

from __future__ import annotations

import struct
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from lost.host.io.kmall import _attitude, read_kmall_pings

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
FILES = sorted(REAL.glob("kongsberg_snippets_tmtgp/*.kmall"))
pytestmark = pytest.mark.skipif(not FILES, reason=f"the real .kmall files are not under {REAL}")


def pykmall_samples(path: Path) -> dict[str, np.ndarray]:
    """Every SKM sample as pykmall's read_EMdgmSKM gives it (dicts), in file order."""
    import contextlib
    import io

    from KMALL.kmall import kmall

    out = {"t": [], "roll": [], "pitch": [], "heave": []}
    reader = kmall(str(path))
    reader.OpenFiletoRead()
    size, at = path.stat().st_size, 0
    with contextlib.redirect_stdout(io.StringIO()):
        while at + 8 <= size:
            reader.FID.seek(at)
            length = struct.unpack("<I", reader.FID.read(4))[0]
            if reader.FID.read(4) == b"#SKM":
                reader.FID.seek(at)
                samples = reader.read_EMdgmSKM()["sample"]["KMdefault"]
                for ours, theirs in (("t", "dgtime"), ("roll", "roll_deg"), ("pitch", "pitch_deg"), ("heave", "heave_m")):
                    out[ours].extend(samples[theirs])
            at += length
    reader.closeFile()
    return {k: np.array(v, dtype=np.float64) for k, v in out.items()}


@pytest.mark.parametrize("path", FILES, ids=lambda p: p.name[:16])
def test_the_skm_samples_are_pykmalls_bit_for_bit(path):
    ours = _attitude(path, Counter(), Counter())
    theirs = pykmall_samples(path)
    order = np.argsort(theirs["t"], kind="stable")
    assert ours["t"].size == theirs["t"].size > 50
    for key in ("t", "roll", "pitch", "heave"):
        np.testing.assert_array_equal(ours[key], theirs[key][order], err_msg=key)


def _with_second_sensor(data: bytes, *, status: int) -> bytes:
    """The file with each SKM datagram followed by a copy from sensor 1 (status ``status``), its roll 5 degrees more."""
    out, at = [], 0
    while at + 8 <= len(data):
        length = struct.unpack_from("<I", data, at)[0]
        frame = data[at:at + length]
        out.append(frame)
        if frame[4:8] == b"#SKM":
            copy = bytearray(frame)
            copy[22], copy[23] = 1, status  # sensorSystem, sensorStatus
            info, count, per = struct.unpack_from("<H", copy, 20)[0], *struct.unpack_from("<2H", copy, 26)
            for k in range(count):
                where = 20 + info + k * per + 40
                struct.pack_into("<f", copy, where, struct.unpack_from("<f", copy, where)[0] + 5.0)
            out.append(bytes(copy))
        at += length
    return b"".join(out)


def test_a_second_attitude_sensor_not_marked_active_is_not_mixed_in(tmp_path):
    path = FILES[0]
    expected = [p.roll_deg for p in read_kmall_pings(path, Counter(), Counter())]
    other = tmp_path / "two_sensors.kmall"
    other.write_bytes(_with_second_sensor(path.read_bytes(), status=0))
    notes = Counter()
    np.testing.assert_array_equal([p.roll_deg for p in read_kmall_pings(other, Counter(), notes)], expected)
    assert notes[f"{other.name}: attitude from SKM sensor 0 (marked active); not used: SKM sensor 1"] == 1


def test_the_second_sensor_marked_active_gives_the_pings_its_attitude(tmp_path):
    path = FILES[0]
    expected = np.array([p.roll_deg for p in read_kmall_pings(path, Counter(), Counter())])
    data = bytearray(_with_second_sensor(path.read_bytes(), status=1))
    at = 0
    while at + 8 <= len(data):  # sensor 0 no longer active
        length = struct.unpack_from("<I", data, at)[0]
        if data[at + 4:at + 8] == b"#SKM" and data[at + 22] == 0:
            data[at + 23] = 0
        at += length
    other = tmp_path / "second_active.kmall"
    other.write_bytes(bytes(data))
    rolls = np.array([p.roll_deg for p in read_kmall_pings(other, Counter(), Counter())])
    finite = np.isfinite(expected)
    assert finite.sum() >= 3
    np.testing.assert_allclose(rolls[finite], expected[finite] + 5.0, atol=1e-5)


def test_an_skm_datagram_holding_fewer_samples_than_it_says_is_skipped_and_counted(tmp_path):
    path = next(p for p in FILES if p.read_bytes().count(b"#SKM") >= 2)
    data, at, damaged = bytearray(path.read_bytes()), 0, False
    while at + 8 <= len(data) and not damaged:
        length = struct.unpack_from("<I", data, at)[0]
        if data[at + 4:at + 8] == b"#SKM":
            struct.pack_into("<H", data, at + 26, 60000)  # numSamplesArray far beyond the datagram
            damaged = True
        at += length
    other = tmp_path / "short_skm.kmall"
    other.write_bytes(bytes(data))
    skipped = Counter()
    pings = list(read_kmall_pings(other, skipped, Counter()))
    assert skipped == Counter({f"{other.name}: damaged datagram 'SKM' (fewer samples than it says)": 1})
    assert len(pings) == len(list(read_kmall_pings(path, Counter(), Counter())))
