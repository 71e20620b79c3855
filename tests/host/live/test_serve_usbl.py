"""USBL fixes in the served navigation: `lost replay` of a scenario with a USBL (its fixes as JSON lines) into `lost serve` gives
the batch navigation of the same pings with each fix in the record whose interval holds it, carried to the record's time."""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import replace

import numpy as np

from lost.host.io.simulated import EPOCH_S, simulated_pings
from lost.host.live.usbl import PlacedFix, UsblPlacer
from lost.host.scenario import load_scenario

from .conftest import SETTINGS, batch_survey_run


def _batch(map_path, pings_path, fixes: list[tuple[float, np.ndarray, np.ndarray]]):
    """`navigate()` on the records `lost run --survey` makes of the pings, each record k >= 1 given the fixes of (t_k-1, t_k]."""
    from lost.host.cli.common import map_uncertainty
    from lost.host.io import read_grid
    from lost.host.io.survey import open_survey
    from lost.host.io.survey_records import SurveyRecorder, survey_records
    from lost.host.nav import NavParameters, navigate

    params = NavParameters()
    grid, _ = map_uncertainty(read_grid(map_path), params)
    survey = open_survey(pings_path, crs=grid.crs)
    recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=SETTINGS["record_s"], window_s=SETTINGS["window_s"],
                              dr_bias_mps=SETTINGS["dr_bias_mps"], start_offset_m=SETTINGS["start_offset_m"], patch_centre=SETTINGS["patch_centre"])
    records = survey_records(survey, recorder)
    times = recorder.epoch_s + records.t_s
    series = {name: np.full(len(records), np.nan) for name in ("usbl_x_m", "usbl_y_m", "usbl_sxx", "usbl_syy", "usbl_sxy")}
    used = np.zeros(len(records), int)
    for k in range(1, len(records)):
        mine = [(t, x, c) for t, x, c in fixes if times[k - 1] < t <= times[k]]
        if not mine:
            continue
        velocity = np.array([records.vel_x_mps[k], records.vel_y_mps[k]])
        information = sum(np.linalg.inv(c) for _, _, c in mine)
        covariance = np.linalg.inv(information)
        position = covariance @ sum(np.linalg.inv(c) @ (x + velocity * (times[k] - t)) for t, x, c in mine)
        series["usbl_x_m"][k], series["usbl_y_m"][k] = position
        series["usbl_sxx"][k], series["usbl_syy"][k], series["usbl_sxy"][k] = covariance[0, 0], covariance[1, 1], covariance[0, 1]
        used[k] = len(mine)
    return navigate(replace(records, **series), grid, params, estimators=("lost", "pmf", "pf")), used


def test_served_usbl_fixes_give_the_batch_navigation_with_the_fixes_in_their_records(usbl_tow, serve_replay, tmp_path, capsys):
    from itertools import islice

    from lost.host.io.crs import transformer
    from lost.host.io.kmall_write import write_kmall_pings

    path, map_path, simulated, crs = usbl_tow
    out, _ = serve_replay((path, map_path), tmp_path, ["--dvl", "none"])
    replayed = capsys.readouterr().out
    assert "its USBL fixes as JSON" in replayed and "DVL" not in replayed.splitlines()[0]
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    sent = np.isfinite(simulated.usbl_x_m)
    received = [line["usbl"] for line in log if "usbl" in line]
    assert len(received) == int(sent.sum()) > 40
    served = [line for line in log if "record" in line]

    # The batch reference: the fixes as sent (latitude, longitude: the scenario's frame there and back into the map's).
    to_lonlat, to_map = transformer(crs, "EPSG:4326"), transformer("EPSG:4326", crs)
    fixes = []
    for k in np.flatnonzero(sent):
        lon, lat = to_lonlat.transform(simulated.usbl_x_m[k], simulated.usbl_y_m[k])
        east, north = to_map.transform(float(lon), float(lat))
        sxy = simulated.usbl_sxy[k]
        fixes.append((EPOCH_S + simulated.t_s[k], np.array([east, north]), np.array([[simulated.usbl_sxx[k], sxy], [sxy, simulated.usbl_syy[k]]])))
    _, _, pings = simulated_pings(load_scenario(path))
    result, used = _batch(map_path, write_kmall_pings(islice(pings, None), tmp_path / "tow.kmall"), fixes)

    assert len(served) == len(result.t_s) == 24
    assert [line["estimates"]["pmf"]["usbl_fixes"] for line in served] == list(used) and (used[1:] > 0).sum() >= 20
    for name in ("lost", "pmf", "pf"):
        track = result.tracks[name]
        mine = [line["estimates"][name] for line in served]
        np.testing.assert_array_equal([(e["east_m"], e["north_m"]) for e in mine], track.position)
        if name != "lost":
            np.testing.assert_array_equal([(e["sxx_m2"], e["syy_m2"], e["sxy_m2"]) for e in mine], track.covariance[:, [0, 1, 0], [0, 1, 1]])
        assert [e["usable"] for e in mine] == list(track.usable)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["server"]["USBL fixes received"] == len(received)
    _assert_batch_run_with_the_fixes_is_the_served_one(simulated, crs, map_path, tmp_path / "tow.kmall", served, used, tmp_path)
    assert summary["navigation"]["USBL fixes used"] == used.sum() and summary["navigation"]["records with a USBL fix"] == (used > 0).sum()
    # Every estimator weighed fixes (the 20 s windows' patches are too sparse on the 30 m map: the fixes alone correct).
    assert summary["estimator_counts"]["pmf"]["fix_updates"] > 10 and summary["estimator_counts"]["pf"]["fix_updates"] > 10
    assert summary["navigation"]["usbl_fix_recentred"] > 0 and summary["navigation"]["patch_too_sparse"] == len(served) - 1


def _assert_batch_run_with_the_fixes_is_the_served_one(simulated, crs, map_path, pings_path, served, used, tmp_path):
    """`lost run --survey --usbl-fixes` on the pings and a file of the very lines `lost replay` sent: the served run's records."""
    from lost.host.live.stream import vehicle_datagrams

    from .test_serve import _assert_log_is_the_batch_runs

    fixes_path = tmp_path / "fixes.jsonl"
    fixes_path.write_bytes(b"".join(d.payload for d in vehicle_datagrams(simulated, crs, dvl_format="none", epoch_s=EPOCH_S)))
    rows, summary = batch_survey_run(map_path, pings_path, fixes_path, tmp_path / "batch")
    _assert_log_is_the_batch_runs(served, rows)
    batch = summary["usbl_fixes"]
    assert batch["placed"]["USBL fixes used"] == used.sum() and batch["placed"]["records with a USBL fix"] == (used > 0).sum()
    assert batch["fixes"] == batch["read"]["JSON usbl lines"] == len(fixes_path.read_text().splitlines())


def test_fixes_of_an_interval_are_carried_to_the_records_time_and_combined_late_and_first_ones_counted():
    counts = Counter()
    placer = UsblPlacer(counts)
    fix = PlacedFix(EPOCH_S + 1.0, np.array([10.0, 20.0]), np.diag([4.0, 4.0]))
    placer.add(fix)
    assert placer.place(EPOCH_S + 2.0, (1.0, 0.0)) is None  # the first record: the navigation starts there
    placer.add(PlacedFix(EPOCH_S + 1.5, np.array([0.0, 0.0]), np.eye(2)))  # its record is stepped: late
    placer.add(PlacedFix(EPOCH_S + 3.0, np.array([100.0, 0.0]), np.diag([1.0, 4.0])))
    placer.add(PlacedFix(EPOCH_S + 6.0, np.array([104.0, 3.0]), np.diag([1.0, 1.0])))
    placer.add(PlacedFix(EPOCH_S + 9.0, np.array([0.0, 0.0]), np.eye(2)))  # the next record's
    position, covariance, n = placer.place(EPOCH_S + 7.0, (1.0, 0.5))
    # Carried to 7 s: (104, 2) with variances 1, 4 and (105, 3.5) with 1, 1; combined by their information.
    assert n == 2
    np.testing.assert_allclose(covariance, np.diag([0.5, 0.8]))
    np.testing.assert_allclose(position, [104.5, 0.8 * (2.0 / 4.0 + 3.5 / 1.0)])
    assert counts["USBL fixes up to the first record (not used: the navigation starts there)"] == 1
    assert counts["USBL fixes after their record was stepped (late; not used)"] == 1
    assert counts["USBL fixes used"] == 2 and counts["records with a USBL fix"] == 1
    assert placer.place(EPOCH_S + 10.0, (0.0, 0.0))[2] == 1



def test_served_usbl_sentences_over_udp_and_a_serial_port_are_the_fixes_they_carry(usbl_tow, serve_replay, tmp_path):
    """The tow's fixes as a ship's USBLs send them: `$PSONLLD` over UDP (its error ellipse from the fix's covariance) and
    `$PSIMSSB` on a serial pty (geographic, radians; no accuracy: the configured default); `lost serve` logs and weighs each."""
    import os

    from lost.host.io.crs import transformer
    from lost.host.live.inputs import UsblFix
    from lost.host.live.nmea import fix_sentences
    from lost.host.live.receiver import LiveDecoder
    from lost.host.live.usbl_nmea import psimssb_sentence, psonlld_sentence

    from .test_serial import _pty, _wait_configured

    path, map_path, simulated, crs = usbl_tow
    to_lonlat = transformer(crs, "EPSG:4326")
    zda = (fix_sentences(EPOCH_S, 0.0, 0.0)[0] + "\r\n").encode()
    udp, serial = [zda], [zda]
    for n, k in enumerate(np.flatnonzero(np.isfinite(simulated.usbl_x_m))):
        lon, lat = to_lonlat.transform(simulated.usbl_x_m[k], simulated.usbl_y_m[k])
        fix = UsblFix(EPOCH_S + float(simulated.t_s[k]), float(lat), float(lon), 700.0, 0.0, 0.0, 0.0)
        if n % 2:
            serial.append((psimssb_sentence(fix) + "\r\n").encode())
            continue
        sxy = simulated.usbl_sxy[k]
        variances, axes = np.linalg.eigh(np.array([[simulated.usbl_sxx[k], sxy], [sxy, simulated.usbl_syy[k]]]))
        direction = float(np.degrees(np.arctan2(axes[0, 1], axes[1, 1])) % 180.0)
        udp.append((psonlld_sentence(fix, major_m=float(np.sqrt(variances[1])), minor_m=float(np.sqrt(variances[0])), direction_deg=direction)
                    + "\r\n").encode())
    master, port = _pty()
    try:
        out, _ = serve_replay((path, map_path), tmp_path, ["--dvl", "none", "--usbl", "none"], junk=tuple(udp), two_ports=True,
                              serial=({"port": port, "kind": "nmea"},), usbl_default_sigma_m=8.0,
                              before_replay=lambda: (_wait_configured(master), os.write(master, b"".join(serial))))
    finally:
        os.close(master)
    expected = LiveDecoder(usbl_default_sigma_m=8.0)
    fixes = [v for line in udp + serial for v in expected.feed(line)]
    assert len(fixes) == len(udp) + len(serial) - 2 > 40
    log = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    received = sorted((line["usbl"] for line in log if "usbl" in line), key=lambda fix: fix["time_utc_s"])
    assert received == [{"time_utc_s": f.time_s, **{k: v for k, v in f.__dict__.items() if k != "time_s"}} for f in sorted(fixes, key=lambda f: f.time_s)]
    summary = json.loads((out / "summary.json").read_text())
    served = [line["estimates"]["pmf"]["usbl_fixes"] for line in log if "record" in line]
    assert summary["navigation"]["USBL fixes used"] == sum(served) > 30 and summary["estimator_counts"]["pmf"]["fix_updates"] > 10
    assert summary["received"]["USBL $PSIMSSB fixes given the default sigma"] == len(serial) - 1
