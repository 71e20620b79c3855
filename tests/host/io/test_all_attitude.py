"""The .all attitude datagrams ('A' and the network attitude 'n') of the real Kongsberg files, and which sensor the pings take.

The samples are checked against a decoding of the datagrams written here with ``struct`` from the layout of
Kongsberg's EM Series datagram formats (the layout pyall and MB-System's ``mbsys_simrad3`` read): the common
header, then for 'A' the sample count, 12 bytes per sample and the sensor system descriptor; for 'n' the sample
count, the descriptor and a spare byte, then per sample 11 bytes and the input datagram's bytes it counts.
"""

from __future__ import annotations

import struct
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from lost.host.io.all_attitude import AttitudeSources
from lost.host.io.all_frames import byte_order, datagrams
from lost.host.io.kongsberg_all import read_all_pings

REAL = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "real_survey"
SNIPPETS = REAL / "kongsberg_snippets_tmtgp"
BELGICA = SNIPPETS / "0077_20221109_123655_Belgica.all"
pytestmark = pytest.mark.skipif(not BELGICA.is_file(), reason=f"the real Kongsberg snippets are not at {SNIPPETS}")
HEADER = struct.Struct("<IBBHIIHH")


def frames(data: bytes) -> list[tuple[int, bytes]]:
    """(offset, datagram with its length word) of each datagram of a whole little-endian .all file."""
    out, at = [], 0
    while at + 4 <= len(data):
        length = int.from_bytes(data[at:at + 4], "little")
        out.append((at, data[at:at + 4 + length]))
        at += 4 + length
    return out


def independent_samples(data: bytes) -> dict[tuple[str, int], np.ndarray]:
    """(type, descriptor) -> rows (time s, roll, pitch, heave, heading) of every 'A' and 'n' datagram, decoded with struct."""
    import datetime as dt

    out: dict[tuple[str, int], list] = {}
    for _, frame in frames(data):
        _, _, kind, _, date, ms, _, _ = HEADER.unpack_from(frame)
        if kind not in b"An":
            continue
        t0 = dt.datetime(date // 10000, date // 100 % 100, date % 100, tzinfo=dt.UTC).timestamp() + ms / 1000.0
        n = struct.unpack_from("<H", frame, 20)[0]
        rows = []
        if kind == ord("A"):
            for k in range(n):
                t, _, roll, pitch, heave, heading = struct.unpack_from("<HHhhhH", frame, 22 + 12 * k)
                rows.append((t0 + t / 1000.0, roll / 100, pitch / 100, heave / 100, heading / 100))
            descriptor = frame[22 + 12 * n]
        else:
            descriptor, at = frame[22], 24
            for _ in range(n):
                t, roll, pitch, heave, heading, nbytes = struct.unpack_from("<HhhhHB", frame, at)
                rows.append((t0 + t / 1000.0, roll / 100, pitch / 100, heave / 100, heading / 100))
                at += 11 + nbytes
            assert at <= len(frame) - 3
        out.setdefault((chr(kind), descriptor), []).extend(rows)
    return {key: np.array(rows) for key, rows in out.items()}


def with_descriptors(data: bytes, new: dict[tuple[str, int], int]) -> bytes:
    """The file with the sensor descriptors of its 'A'/'n' datagrams replaced as ``new`` says, checksums recomputed."""
    out = bytearray(data)
    for at, frame in frames(data):
        kind = chr(frame[5])
        if kind not in "An":
            continue
        where = 22 + 12 * struct.unpack_from("<H", frame, 20)[0] if kind == "A" else 22
        descriptor = frame[where]
        if (kind, descriptor) in new:
            out[at + where] = new[(kind, descriptor)]
            body = bytes(out[at + 5:at + len(frame) - 3])
            out[at + len(frame) - 2:at + len(frame)] = (sum(body) & 0xFFFF).to_bytes(2, "little")
    return bytes(out)


def reader_samples(path: Path) -> dict[str, np.ndarray]:
    order = byte_order(path)
    sources = AttitudeSources(path, order)
    skipped = Counter()
    for header, data in datagrams(path, {ord("A"), ord("n")}, skipped, order):
        sources.add(header, data, skipped)
    assert not skipped
    return sources.samples()


def with_network() -> list[Path]:
    return [p for p in sorted(SNIPPETS.glob("*.all")) + sorted(REAL.glob("ausseabed_*/*.all")) if b"\x02n" in p.read_bytes()]


def test_every_network_attitude_sample_of_the_real_files_is_the_independent_decodings():
    files = with_network()
    assert len(files) >= 8  # EM2040/EM2045/EM710 systems log 'n' beside 'A'
    compared = 0
    for path in files:
        ours = reader_samples(path)
        theirs = independent_samples(path.read_bytes())
        for (kind, descriptor), rows in theirs.items():
            number = (descriptor >> 4) & 3
            name = f"'A' motion sensor {number + 1}" if kind == "A" else f"'n' attitude velocity sensor {number - 1}"
            np.testing.assert_array_equal(ours[name], rows, err_msg=f"{path.name} {name}")
            compared += len(rows) if kind == "n" else 0
        assert len(ours) == len(theirs)
    assert compared > 3000


def _interpolated(rows: np.ndarray, times: np.ndarray) -> np.ndarray:
    rows = rows[np.argsort(rows[:, 0], kind="stable")]
    return np.column_stack([np.interp(times, rows[:, 0], rows[:, k]) for k in (1, 2, 3)])


def _pings_attitude(path: Path) -> tuple[np.ndarray, np.ndarray, Counter]:
    notes = Counter()
    pings = list(read_all_pings(path, Counter(), notes))
    return np.array([p.time_s for p in pings]), np.array([[p.roll_deg, p.pitch_deg, p.heave_m] for p in pings]), notes


def test_the_pings_take_the_attitude_of_the_sensor_its_datagrams_mark_active():
    # Belgica's EM2040 logs 'A' from two motion sensors and 'n' from two network sensors; only 'A' sensor 1
    # (descriptor 0x01: roll, pitch, heave active) is the sonar's.
    theirs = independent_samples(BELGICA.read_bytes())
    assert set(theirs) == {("A", 0x01), ("A", 0x1E), ("n", 0x3E), ("n", 0x6E)}
    times, attitude, notes = _pings_attitude(BELGICA)
    inside = (times > theirs[("A", 0x01)][:, 0].min()) & (times < theirs[("A", 0x01)][:, 0].max())
    assert inside.sum() >= 5
    np.testing.assert_allclose(attitude[inside], _interpolated(theirs[("A", 0x01)], times[inside]), atol=1e-9)
    other = _interpolated(theirs[("A", 0x1E)], times[inside])
    assert np.abs(attitude[inside] - other).max() > 0.01  # the other sensor differs: the choice matters
    note = next(n for n in notes if "mark active" in n)
    assert "roll, pitch, heave from 'A' motion sensor 1" in note
    assert note.endswith("not used: 'A' motion sensor 2, 'n' attitude velocity sensor 1, 'n' attitude velocity sensor 2")


def test_a_network_sensor_marked_active_gives_the_pings_attitude(tmp_path):
    # The same real file with the descriptors changed: 'A' sensor 1 inactive, 'n' sensor 1 active.
    path = tmp_path / "belgica_n_active.all"
    path.write_bytes(with_descriptors(BELGICA.read_bytes(), {("A", 0x01): 0x0F, ("n", 0x6E): 0x60}))
    network = independent_samples(path.read_bytes())[("n", 0x60)]
    times, attitude, notes = _pings_attitude(path)
    inside = (times > network[:, 0].min()) & (times < network[:, 0].max())
    assert inside.sum() >= 5
    np.testing.assert_allclose(attitude[inside], _interpolated(network, times[inside]), atol=1e-9)
    assert any("roll, pitch, heave from 'n' attitude velocity sensor 1" in n for n in notes)


def test_heave_from_another_sensor_than_roll_and_pitch(tmp_path):
    # Kongsberg's installation names the roll/pitch and the heave sensor apart (ARO, AHE): each quantity its own.
    path = tmp_path / "belgica_split.all"
    path.write_bytes(with_descriptors(BELGICA.read_bytes(), {("A", 0x01): 0x09, ("n", 0x6E): 0x66}))  # A: roll, pitch; n: heave
    theirs = independent_samples(path.read_bytes())
    times, attitude, _ = _pings_attitude(path)
    inside = (times > theirs[("n", 0x66)][:, 0].min()) & (times < theirs[("A", 0x09)][:, 0].max()) & (times > theirs[("A", 0x09)][:, 0].min())
    np.testing.assert_allclose(attitude[inside, :2], _interpolated(theirs[("A", 0x09)], times[inside])[:, :2], atol=1e-9)
    np.testing.assert_allclose(attitude[inside, 2], _interpolated(theirs[("n", 0x66)], times[inside])[:, 2], atol=1e-9)


def test_a_file_whose_datagrams_mark_no_sensor_active_uses_motion_sensor_1_and_says_so(tmp_path):
    path = tmp_path / "belgica_none.all"
    path.write_bytes(with_descriptors(BELGICA.read_bytes(), {("A", 0x01): 0x0F}))
    theirs = independent_samples(path.read_bytes())
    times, attitude, notes = _pings_attitude(path)
    inside = (times > theirs[("A", 0x0F)][:, 0].min()) & (times < theirs[("A", 0x0F)][:, 0].max())
    np.testing.assert_allclose(attitude[inside], _interpolated(theirs[("A", 0x0F)], times[inside]), atol=1e-9)
    assert any("no attitude datagram marks roll active; roll from 'A' motion sensor 1" in n for n in notes)
