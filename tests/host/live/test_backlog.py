"""The bounded queue between the receiving thread and the navigation: full, it drops its oldest value and counts it by kind;
the receiving thread never waits; a flood into `LiveServer` ends with every value either navigated or counted."""

from __future__ import annotations

import sys
import tempfile
import threading
import time
from itertools import islice
from pathlib import Path

import pytest

from lost.host.io.survey import Ping
from lost.host.live.backlog import Backlog


def test_a_full_queue_drops_its_oldest_values_and_counts_them_by_kind():
    backlog = Backlog(3)
    for item in [(0.0, "a"), (1.0, 7), (2.0, "b"), (3.0, "c"), (4.0, 2.5)]:
        backlog.put(item)
    assert [backlog.get(0.0) for _ in range(3)] == [(2.0, "b"), (3.0, "c"), (4.0, 2.5)]
    assert backlog.get(0.0) is None and len(backlog) == 0
    assert backlog.counts() == {"values dropped from the full queue (oldest first): str": 1,
                                "values dropped from the full queue (oldest first): int": 1}
    assert backlog.deepest == 3


def test_putting_never_waits_and_getting_waits_only_its_timeout():
    backlog = Backlog(10)
    started = time.monotonic()
    for k in range(50_000):  # nobody takes: the puts still all return at once
        backlog.put((float(k), k))
    assert time.monotonic() - started < 2.0
    assert len(backlog) == 10 and sum(backlog.counts().values()) == 49_990
    assert [backlog.get(0.0)[1] for _ in range(10)] == list(range(49_990, 50_000))
    started = time.monotonic()
    assert backlog.get(0.1) is None
    assert 0.09 <= time.monotonic() - started < 1.0
    later = threading.Timer(0.05, backlog.put, args=((1.0, "late"),))
    later.start()
    assert backlog.get(5.0) == (1.0, "late")
    later.join()


@pytest.mark.parametrize("size", [0, -1, 2.5])
def test_a_queue_must_hold_at_least_one_value(size):
    with pytest.raises(ValueError, match="at least one value"):
        Backlog(size)


class _Flood:
    """A receiver whose thread puts a tow's decoded values all at once (a replay at --speed 0 far faster than the navigation)."""

    def __init__(self, pings) -> None:
        from lost.host.live.receiver import LiveDecoder
        from lost.host.live.stream import live_datagrams

        self.decoder = LiveDecoder()
        self.values = [value for datagram in live_datagrams(pings) for value in self.decoder.feed(datagram.payload)]
        self.values += self.decoder.finish()
        self.put = 0

    def run(self, on_value) -> None:
        for value in self.values:
            on_value(value)
            self.put += 1

    def stop(self) -> None:
        pass


def test_a_flood_faster_than_the_navigation_keeps_the_latest_values_and_counts_the_rest():
    from lost.host.cli.common import map_uncertainty
    from lost.host.io.simulated import simulated_pings
    from lost.host.io.survey_records import SurveyRecorder
    from lost.host.live.navigator import LiveNavigator
    from lost.host.live.outputs import RunLog, UdpSender
    from lost.host.live.server import LiveServer
    from lost.host.nav import NavParameters
    from lost.host.scenario import builtin_scenario_path, load_scenario

    grid, _, pings = simulated_pings(load_scenario(builtin_scenario_path("short_exact_map")))
    pings = list(islice(pings, 200))
    params = NavParameters()
    grid, _ = map_uncertainty(grid, params)
    recorder = SurveyRecorder(node_m=grid.node_m, patch_shape=(10, 10), interval_s=5.0, window_s=20.0, patch_centre="soundings")
    flood = _Flood(pings)
    with tempfile.TemporaryDirectory() as folder:
        log, sender = RunLog(Path(folder) / "log.jsonl"), UdpSender([])
        server = LiveServer(flood, LiveNavigator(grid, params, ("pf",), recorder), sender, log, idle_stop_s=0.5, status_s=60.0,
                            status_stream=sys.stderr, queue_max_values=40)
        taken: list[object] = []
        take = server.take
        server.take = lambda received, value: (taken.append(value), take(received, value))[-1]
        summary = server.run()
        log.close()
        sender.close()
    queue = summary["queue"]
    dropped = sum(n for key, n in queue.items() if key.startswith("values dropped"))
    assert queue["max_values"] == 40 and queue["deepest"] == 40 and dropped > 100
    assert len(taken) + dropped == flood.put  # every value navigated or counted, none lost unseen
    assert queue["values dropped from the full queue (oldest first): Ping"] == len(pings) - sum(isinstance(v, Ping) for v in taken)
    # The oldest went: the last pings of the tow are among those navigated, and the drops are in the status line's.
    assert [p.time_s for p in pings[-5:]] == [v.time_s for v in taken if isinstance(v, Ping)][-5:]
    assert "values dropped from the full queue (oldest first): Ping" in server.status_line()
    assert summary["ended"].startswith("no datagram") and summary["records"] >= 1
