"""The bounded queue between `lost serve`'s receiving thread and its navigation.

The receiving thread must never wait: a reader that blocks leaves the datagrams in the socket's buffer, where the
kernel drops them unseen when it fills. So :meth:`Backlog.put` never blocks; when the queue already holds
``max_values`` decoded values, the **oldest** is dropped to make room, and counted by its kind.

Why the oldest: a navigator on a ship serves the position of the vehicle now. A backlog (a navigation slower than
the stream: a slow device correlator, a replay at ``--speed 0``) means the values at the head of the queue are the
stalest; dropping them keeps the wait bounded and the estimates current, the navigation resuming on the latest
pings after a gap it counts as any other (a silent interval, pings missing from the ping counter). Dropping the
newest instead would hold the estimates at the queue's full delay for as long as the backlog lasts.
"""

from __future__ import annotations

import threading
import time
from collections import Counter, deque

__all__ = ["Backlog", "DEFAULT_MAX_VALUES"]

#: Decoded values the queue holds at most: at 1 Hz pings and about seven values a ping (its .kmall ping, NMEA fixes
#: and headings, the vehicle's sensors), some 24 minutes of stream; nothing waits at real time.
DEFAULT_MAX_VALUES = 10_000


class Backlog:
    """A FIFO of ``(received, value)`` pairs of at most ``max_values``, the oldest dropped and counted when full.

    Parameters
    ----------
    max_values : int
        The most values held; at least 1.

    Attributes
    ----------
    dropped : Counter
        ``"values dropped from the full queue (oldest first): KIND"`` -> count, KIND the value's type name.
    deepest : int
        The most values the queue has held at once.
    """

    def __init__(self, max_values: int = DEFAULT_MAX_VALUES) -> None:
        if not isinstance(max_values, int) or max_values < 1:
            raise ValueError(f"the queue must hold at least one value, got max_values={max_values!r}")
        self.max_values = max_values
        self.dropped: Counter[str] = Counter()
        self.deepest = 0
        self._items: deque = deque()
        self._ready = threading.Condition()

    def put(self, item: tuple[float, object]) -> None:
        """Add ``(received, value)`` at the tail, never waiting; a full queue drops its head first (counted)."""
        with self._ready:
            if len(self._items) >= self.max_values:
                _, oldest = self._items.popleft()
                self.dropped[f"values dropped from the full queue (oldest first): {type(oldest).__name__}"] += 1
            self._items.append(item)
            self.deepest = max(self.deepest, len(self._items))
            self._ready.notify()

    def get(self, timeout: float) -> tuple[float, object] | None:
        """The head of the queue, waiting up to ``timeout`` seconds for one; None if none came."""
        deadline = time.monotonic() + timeout
        with self._ready:
            while not self._items:
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self._ready.wait(left)
            return self._items.popleft()

    def __len__(self) -> int:
        with self._ready:
            return len(self._items)

    def counts(self) -> Counter[str]:
        """A copy of the drops, safe to read while the receiving thread puts."""
        with self._ready:
            return Counter(self.dropped)
