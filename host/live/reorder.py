"""Pings back into time order: a small buffer that holds each received ping for a lag, then lets it go in time order.

Reordered datagrams can complete pings out of time order (a ping's #MRZ, or its last part, delayed past the next
ping's); the recorder makes records of pings in time order. :class:`PingReorder` holds each ping until either a
ping at least ``lag_s`` later in ping time has arrived, or it has been held ``hold_s`` of wall-clock time (monotonic
seconds, :meth:`~PingReorder.expire`: the stream at real time, where the next ping is a ping interval away), and
releases the pings it holds in time order (pings of one time, two heads, in the order they came). A ping that
arrives after a later one was released has missed its slot: it is dropped and counted (``late``), never given to
the recorder out of order.

A ping that carries its sonar's ping counter (``sequence``: the MRZ's ``pingCnt``) goes at once when it follows
the last ping let go in that count (the next number, or the same: another head's ping of one ping): no earlier
ping can still come. So a stream without faults is not held at all; a ping after a gap (a ping lost, or late) is.

The hold is what reordering costs: at real time a ping after a gap waits up to ``hold_s`` before the navigation
sees it, so its record's estimate comes up to ``hold_s`` later; a datagram delayed longer than that on the network
makes its ping late. ``lag_s = 0`` releases every ping at once (no reordering undone; late pings still counted and dropped).
"""

from __future__ import annotations

import heapq
import math
from collections import Counter

from ..io.survey import Ping

__all__ = ["PingReorder", "LATE"]

#: The counter of pings that came after their slot (dropped).
LATE = "pings late for time order, after a later one went on (dropped)"


class PingReorder:
    """Pings in as they complete, out in time order after ``lag_s`` (see the module); ``counts`` holds ``LATE``."""

    def __init__(self, lag_s: float, counts: Counter | None = None, *, hold_s: float | None = None) -> None:
        hold_s = lag_s if hold_s is None else hold_s
        for name, value in (("lag", lag_s), ("hold", hold_s)):
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ValueError(f"the reorder {name} must be a finite number of seconds >= 0, got {value!r}")
        self.lag_s, self.hold_s = float(lag_s), min(float(hold_s), float(lag_s))
        self.counts: Counter[str] = counts if counts is not None else Counter()
        self._held: list[tuple[float, int, float, float, int | None, Ping]] = []  # (ping time, arrival order, decoded, entered, counter, ping)
        self._order = 0
        self._released_s = -math.inf  # the time of the latest ping let go
        self._newest_s = -math.inf  # the latest ping time seen
        self._released_sequence: int | None = None  # the ping counter of the latest ping let go

    def __len__(self) -> int:
        return len(self._held)

    def add(self, ping: Ping, received: float, now: float | None = None, sequence: int | None = None) -> list[tuple[Ping, float]]:
        """Take a ping decoded at monotonic time ``received``, given to the buffer at ``now`` (default ``received``): its hold
        counts from ``now`` (a backlog's pings are not let go at once for having waited in a queue); ``sequence`` its
        ping counter, if known. The pings now released, in time order, with their ``received`` times."""
        if ping.time_s < self._released_s:
            self.counts[LATE] += 1
            return []
        heapq.heappush(self._held, (ping.time_s, self._order, received, received if now is None else now, sequence, ping))
        self._order += 1
        self._newest_s = max(self._newest_s, ping.time_s)
        return self._release(lambda entry: entry[0] <= self._newest_s - self.lag_s or self._follows(entry[4]))

    def _follows(self, sequence: int | None) -> bool:
        """The ping counter follows the last let go (no ping can come between)."""
        return sequence is not None and self._released_sequence is not None and 0 <= sequence - self._released_sequence <= 1

    def wait_s(self, now: float) -> float:
        """Seconds from ``now`` until a held ping is due to go by its hold (infinity when none is held)."""
        return max(min(entry[3] for entry in self._held) + self.hold_s - now, 0.0) if self._held else math.inf

    def expire(self, now: float) -> list[tuple[Ping, float]]:
        """Release the pings held ``hold_s`` of wall-clock time by ``now`` (and every earlier ping before them)."""
        if not self._held:
            return []
        due = [entry[0] for entry in self._held if now - entry[3] >= self.hold_s]
        if not due:
            return []
        until = max(due)
        return self._release(lambda entry: entry[0] <= until)

    def finish(self) -> list[tuple[Ping, float]]:
        """The end of the stream: every ping held, in time order."""
        return self._release(lambda entry: True)

    def _release(self, ready) -> list[tuple[Ping, float]]:
        out = []
        while self._held and ready(self._held[0]):
            time_s, _, received, _, sequence, ping = heapq.heappop(self._held)
            self._released_s = time_s
            self._released_sequence = sequence
            out.append((ping, received))
        return out
