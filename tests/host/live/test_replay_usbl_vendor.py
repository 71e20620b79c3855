"""`lost replay --usbl psonlld|psimssb`: a simulated USBL's fixes sent as the ships' USBLs send them, decoded back to the JSON
lines' fixes within the sentences' precision, and served end to end: `lost replay` into `lost serve` gives the batch run with
the same sentences record for record, and the batch run with the JSON fixes within the sentences' rounding."""

from __future__ import annotations

import json
from itertools import islice

import numpy as np
import pytest

from lost.host.io.kmall_write import write_kmall_pings
from lost.host.io.simulated import EPOCH_S, simulated_pings
from lost.host.live.inputs import UsblFix
from lost.host.live.nmea import fix_sentences
from lost.host.live.receiver import LiveDecoder
from lost.host.live.stream import live_datagrams, usbl_line, vehicle_datagrams
from lost.host.scenario import load_scenario

from .conftest import batch_survey_run
from .test_serve import _assert_log_is_the_batch_runs


def _decoded(payloads: list[bytes]) -> list[UsblFix]:
    decoder = LiveDecoder()
    decoder.feed((fix_sentences(EPOCH_S, 0.0, 0.0)[0] + "\r\n").encode())  # a ZDA: the date
    return [v for payload in payloads for v in decoder.feed(payload) if isinstance(v, UsblFix)]


def _covariance(fix: UsblFix) -> np.ndarray:
    return np.array([[fix.sxx_m2, fix.sxy_m2], [fix.sxy_m2, fix.syy_m2]])


def test_vendor_sentences_decode_to_the_json_fixes_within_their_precision(usbl_tow):
    _, _, simulated, crs = usbl_tow
    sent = {fmt: [d.payload for d in vehicle_datagrams(simulated, crs, dvl_format="none", epoch_s=EPOCH_S, usbl_format=fmt)]
            for fmt in ("json", "psonlld", "psimssb")}
    assert all(p.startswith(b"$PSONLLD") for p in sent["psonlld"]) and all(p.startswith(b"$PSIMSSB") for p in sent["psimssb"])
    fixes = {fmt: _decoded(payloads) for fmt, payloads in sent.items()}
    json_fixes = fixes["json"]
    assert len(json_fixes) == len(fixes["psonlld"]) == len(fixes["psimssb"]) == int(np.isfinite(simulated.usbl_x_m).sum()) > 40
    for reference, ellipse, accuracy in zip(json_fixes, fixes["psonlld"], fixes["psimssb"], strict=True):
        assert ellipse.time_s == pytest.approx(reference.time_s, abs=5e-4) and accuracy.time_s == pytest.approx(reference.time_s, abs=5e-3)
        assert abs(ellipse.lat_deg - reference.lat_deg) <= 5e-9 and abs(ellipse.lon_deg - reference.lon_deg) <= 5e-9
        assert abs(accuracy.lat_deg - reference.lat_deg) <= 1e-8 and abs(accuracy.lon_deg - reference.lon_deg) <= 1e-8
        truth = _covariance(reference)
        largest = np.linalg.eigvalsh(truth)[-1]
        # The ellipse's axes to 0.01 m and its direction to 0.01 degree: the covariance to about a sigma's 1e-3.
        np.testing.assert_allclose(_covariance(ellipse), truth, atol=0.01 * np.sqrt(largest) + 1e-3 * largest)
        # $PSIMSSB's one accuracy: the larger semi-axis, isotropic, so never below the fix's own spread in any direction.
        assert accuracy.sxy_m2 == 0.0 and accuracy.sxx_m2 == accuracy.syy_m2 == pytest.approx(largest, abs=0.01 * np.sqrt(largest) + 1e-4)


def test_an_unknown_usbl_format_is_refused():
    with pytest.raises(ValueError, match="usbl_format must be one of"):
        usbl_line(UsblFix(EPOCH_S, 0.0, 0.0, 100.0, 4.0, 4.0, 0.0), "ptsag")


def test_replayed_psonlld_served_equals_the_batch_run_with_the_sentences_and_is_the_json_runs_within_rounding(usbl_tow, serve_replay,
                                                                                                           tmp_path, capsys):
    path, map_path, simulated, crs = usbl_tow
    out, _ = serve_replay((path, map_path), tmp_path, ["--dvl", "none", "--usbl", "psonlld"])
    replayed = capsys.readouterr().out
    assert "its USBL fixes as $PSONLLD" in replayed
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    served = [line for line in log if "record" in line]

    # What the server logged is what the receiver makes of the stream `lost replay` sent (the fix of the first ping's time
    # comes before any ZDA or .kmall datagram: counted, not dated).
    _, _, pings = simulated_pings(load_scenario(path))
    pings = list(pings)
    vehicle = vehicle_datagrams(simulated, crs, dvl_format="none", epoch_s=EPOCH_S, usbl_format="psonlld")
    decoder = LiveDecoder()
    expected = [v for d in live_datagrams(iter(pings), vehicle=vehicle) for v in decoder.feed(d.payload) if isinstance(v, UsblFix)]
    received = [line["usbl"] for line in log if "usbl" in line]
    assert received == [{"time_utc_s": f.time_s, **{k: v for k, v in f.__dict__.items() if k != "time_s"}} for f in expected]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["received"]["USBL $PSONLLD before any ZDA or .kmall datagram (no date; skipped)"] == 1
    assert summary["received"]["USBL $PSONLLD fixes dated by the ZDA"] == len(received) > 40

    pings_path = write_kmall_pings(islice(pings, None), tmp_path / "tow.kmall")
    sentences = tmp_path / "fixes.nmea"
    sentences.write_bytes(b"".join(d.payload for d in vehicle_datagrams(simulated, crs, dvl_format="none", epoch_s=EPOCH_S,
                                                                        usbl_format="psonlld")))
    rows, batch = batch_survey_run(map_path, pings_path, sentences, tmp_path / "batch_psonlld")
    _assert_log_is_the_batch_runs(served, rows)
    assert batch["usbl_fixes"]["placed"]["USBL fixes used"] == summary["navigation"]["USBL fixes used"] > 30

    json_lines = tmp_path / "fixes.jsonl"
    json_lines.write_bytes(b"".join(d.payload for d in vehicle_datagrams(simulated, crs, dvl_format="none", epoch_s=EPOCH_S)))
    rows, _ = batch_survey_run(map_path, pings_path, json_lines, tmp_path / "batch_json")
    # The ellipse's 0.01 m and 0.01 degree move the fixes' weights by about 1e-3: the PMF and the patent pipeline by
    # millimetres, the PF by up to decimetres (its resampling draws on those weights), each usable flag the same.
    for name, within_m in (("lost", 0.02), ("pmf", 0.02), ("pf", 0.5)):
        column = "est" if name == "lost" else name
        moved = [max(abs(line["estimates"][name]["east_m"] - float(row[f"{column}_x_m"])),
                     abs(line["estimates"][name]["north_m"] - float(row[f"{column}_y_m"]))) for line, row in zip(served, rows, strict=True)]
        assert max(moved) < within_m, (name, moved)
        if name != "lost":
            assert [line["estimates"][name]["usable"] for line in served] == [bool(int(row[f"{name}_usable"])) for row in rows]
    np.testing.assert_allclose([line["estimates"]["pmf"]["sxx_m2"] for line in served], [float(row["pmf_sxx"]) for row in rows], rtol=0.01)
