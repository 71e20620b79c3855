"""The device correlator falls back to software when it stops answering and goes back when it answers: the served
estimates are the software run's bit for bit, each switch said on the status line and in the log."""

from __future__ import annotations

import io
import json
from itertools import islice
from types import SimpleNamespace

import pytest

from lost.host.correlator import BACKENDS
from lost.host.correlator.backends import DeviceBackend
from lost.host.correlator.transports import InProcessTransport
from lost.host.io.simulated import simulated_pings
from lost.host.io.survey_records import SurveyRecorder
from lost.host.live.fallback import FallbackBackend, with_fallback
from lost.host.live.navigator import LiveNavigator
from lost.host.live.outputs import RunLog, UdpSender
from lost.host.live.receiver import LiveDecoder
from lost.host.live.server import LiveServer
from lost.host.nav import NavParameters
from lost.host.scenario import builtin_scenario_path, load_scenario
from lost.model.device import DeviceModel, reference_info

ESTIMATORS = ("lost", "pmf", "pf")


class SilentableTransport(InProcessTransport):
    """The reference device in-process, made to stop answering (requests go nowhere, as down a pulled cable) and come back."""

    def __init__(self, device: DeviceModel, switch: dict) -> None:
        super().__init__(device, timeout_s=0.001)
        self._switch = switch

    def write(self, data: bytes) -> None:
        if self._switch["answering"]:
            super().write(data)


@pytest.fixture(scope="module")
def tow():
    grid, _, pings = simulated_pings(load_scenario(builtin_scenario_path("short_exact_map")))
    return grid, list(islice(pings, 80))


def _navigator(grid, backend: str) -> LiveNavigator:
    recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=5.0, window_s=20.0, patch_centre="soundings",
                              start_offset_m=(30.0, -20.0), dr_bias_mps=(0.1, 0.05))
    return LiveNavigator(grid, NavParameters(backend=backend), ESTIMATORS, recorder)


def _values(estimates) -> list[tuple]:
    """What the log keeps of each estimate (missing values as None)."""
    rows = [e.as_dict() for e in estimates]
    return [(d["record"], d["estimator"], d["east_m"], d["north_m"], (d["sxx_m2"], d["syy_m2"], d["sxy_m2"]), d["usable"], d["stage"], d["held"])
            for d in rows]


def test_a_device_that_stops_answering_and_comes_back_serves_the_software_runs_estimates_bit_for_bit(tow, monkeypatch, tmp_path):
    grid, pings = tow
    software = _navigator(grid, "software")
    expected = [e for p in pings for e in software.add(p)] + software.finish()

    switch, now = {"answering": True}, {"t": 0.0}
    info = reference_info(tile_shape=(96, 96), area_shape=(48, 48), patch_shape=(10, 10), exclusion_radius=5)
    monkeypatch.setitem(BACKENDS, "fpga", DeviceBackend("fpga", lambda: SilentableTransport(DeviceModel(info), switch)))
    log, sender, status = RunLog(tmp_path / "log.jsonl"), UdpSender([]), io.StringIO()
    with with_fallback("fpga", retry_s=10.0, clock=lambda: now["t"]) as fallback:
        navigator = _navigator(grid, "fpga")
        server = LiveServer(SimpleNamespace(decoder=LiveDecoder()), navigator, sender, log, status_stream=status,
                            reorder_lag_s=0.0, fallback=fallback)
        lines = []
        for ping in pings:
            t = ping.time_s - pings[0].time_s
            now["t"] = t
            switch["answering"] = not 22 <= t < 50  # silent from 22 s; tried at 32 and 42 s, unanswered; back at 52 s
            server.take(0.0, ping)
            if t in (30.0, 60.0):
                lines.append(server.status_line())
        server._serve(navigator.finish(), None, None)
        summary = server.summary()
    log.close()
    sender.close()
    assert BACKENDS["fpga"] is not fallback  # the registry given back
    served = [json.loads(line) for line in (tmp_path / "log.jsonl").read_text().splitlines()]
    records = [line for line in served if "record" in line]
    got = [(line["record"], name, e["east_m"], e["north_m"], (e["sxx_m2"], e["syy_m2"], e["sxy_m2"]), e["usable"], e["stage"], e["held"])
           for line in records for name, e in line["estimates"].items()]
    assert got == _values(expected)  # JSON floats: the shortest repr of each double, read back exactly
    counts = summary["correlator"]
    assert counts["device stopped answering"] == 1 and counts["device back"] == 1 and counts["device retries unanswered"] == 2
    assert counts["correlations on the device"] > 10 and counts["correlations in software (the device not answering)"] > 10
    assert summary["correlator"]["serving"] == "fpga" and "DeviceTimeout" in summary["correlator"]["last_failure"]
    switches = [line["correlator"] for line in served if "correlator" in line]
    assert [s["serving"] for s in switches] == ["software", "fpga"] and "not answering" in switches[0]["reason"]
    assert "correlator software (fpga not answering)" in lines[0] and "correlator fpga;" in lines[1]
    assert status.getvalue().count("lost serve: correlator now") == 2


def test_a_fallback_needs_a_positive_retry():
    with pytest.raises(ValueError, match="retry_s must be a positive"):
        FallbackBackend(BACKENDS["software"], retry_s=0.0)
