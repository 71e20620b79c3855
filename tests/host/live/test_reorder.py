"""Pings back into time order: reordered datagrams complete pings out of order; the buffer lets them go in order, late ones counted."""

from __future__ import annotations

import math
from collections import Counter
from itertools import islice

import pytest

from lost.host.io.simulated import simulated_pings
from lost.host.live.receiver import LiveDecoder
from lost.host.live.reorder import LATE, PingReorder
from lost.host.live.stream import Faults, live_datagrams, with_faults
from lost.host.scenario import builtin_scenario_path, load_scenario


@pytest.fixture(scope="module")
def arrivals():
    """The pings of 150 s of the short tow as the receiver completes them, with 10 % of datagrams sent 8 later (a ping is 6)."""
    _, _, pings = simulated_pings(load_scenario(builtin_scenario_path("short_exact_map")))
    pings = list(islice(pings, 150))
    decoder, drawn = LiveDecoder(), Counter()
    out = []
    for datagram in with_faults(live_datagrams(pings), Faults(reorder=0.1, reorder_by=8, seed=4), drawn):
        out += [(value, decoder.sequence(value)) for value in decoder.feed(datagram.payload) if hasattr(value, "beams")]
    assert drawn["reordered"] > 20
    return pings, [ping for ping, _ in out], [sequence for _, sequence in out]


def _overtaken(times: list[float]) -> int:
    """Pings that arrive after a later one."""
    latest, count = float("-inf"), 0
    for t in times:
        count += t < latest
        latest = max(latest, t)
    return count


def test_reordered_datagrams_make_pings_arrive_out_of_time_order_and_the_buffer_puts_them_back(arrivals):
    pings, arrived, _ = arrivals
    assert len(arrived) == len(pings) and _overtaken([p.time_s for p in arrived]) >= 3
    buffer = PingReorder(1.5)
    released = [ping for k, ping in enumerate(arrived) for ping, _ in buffer.add(ping, float(k))]
    assert len(buffer) > 0
    released += [ping for ping, _ in buffer.finish()]
    assert [p.time_s for p in released] == [p.time_s for p in pings]
    assert buffer.counts[LATE] == 0


def test_without_a_lag_the_pings_that_missed_their_slot_are_dropped_and_counted_as_late(arrivals):
    _, arrived, _ = arrivals
    buffer = PingReorder(0.0)
    released = [ping for ping in arrived for ping, _ in buffer.add(ping, 0.0)]
    assert len(buffer) == 0  # nothing held
    times = [p.time_s for p in released]
    assert times == sorted(times)
    assert buffer.counts[LATE] == _overtaken([p.time_s for p in arrived]) == len(arrived) - len(released) > 0


def test_a_ping_held_its_lag_of_wall_time_goes_on_when_the_stream_pauses(arrivals):
    pings, _, _ = arrivals
    buffer = PingReorder(1.5)
    assert buffer.add(pings[0], 10.0) == [] and buffer.add(pings[1], 10.2) == []  # 1 s apart in ping time: both held
    assert [p.time_s for p, _ in buffer.expire(11.4)] == []
    assert [(p.time_s, received) for p, received in buffer.expire(11.55)] == [(pings[0].time_s, 10.0)]
    assert [p.time_s for p, _ in buffer.expire(11.7)] == [pings[1].time_s]
    with pytest.raises(ValueError, match="reorder lag"):
        PingReorder(-1.0)
    with pytest.raises(ValueError, match="reorder hold"):
        PingReorder(0.5, hold_s=math.nan)


def test_the_wall_clock_hold_counts_from_the_buffer_not_from_the_decoding(arrivals):
    pings, _, _ = arrivals
    buffer = PingReorder(0.5, hold_s=0.05)
    assert buffer.add(pings[0], received=1.0, now=10.0) == []  # decoded at 1 s, waited in a backlog until 10 s
    assert buffer.wait_s(10.0) == pytest.approx(0.05) and buffer.expire(10.04) == []
    assert [(p.time_s, received) for p, received in buffer.expire(10.05)] == [(pings[0].time_s, 1.0)]
    assert buffer.wait_s(10.05) == math.inf


def test_a_ping_that_follows_the_last_in_the_ping_counter_goes_at_once_and_only_a_gap_is_held(arrivals):
    pings, arrived, sequences = arrivals
    by_counter = sorted(zip(sequences, arrived, strict=True), key=lambda pair: pair[0])
    assert [p.time_s for _, p in by_counter] == [p.time_s for p in pings]  # the counter runs with the time
    buffer = PingReorder(1.5, hold_s=1.5)
    released, held_after = [], []
    for ping, sequence in zip(arrived, sequences, strict=True):
        released += [p for p, _ in buffer.add(ping, 0.0, 0.0, sequence)]
        held_after.append(len(buffer))
    released += [p for p, _ in buffer.finish()]
    assert [p.time_s for p in released] == [p.time_s for p in pings] and buffer.counts[LATE] == 0
    # Held only behind a gap: at the start (nothing let go yet), and while an overtaken ping is still on its way.
    assert 3 <= sum(n > 0 for n in held_after) < len(arrived) // 4
    # In counter order nothing waits once the first ping has gone (by the lag, two pings later).
    in_order = PingReorder(1.5, hold_s=1.5)
    out = [len(in_order.add(ping, 0.0, 0.0, sequence)) for sequence, ping in by_counter]
    assert out[:3] == [0, 0, 3] and set(out[3:]) == {1}
