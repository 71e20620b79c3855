"""The serving loop of `lost serve`: a receiving thread, the navigation on the main thread, outputs, status, summary.

:class:`UdpReceiver` runs on its own thread and puts each decoded value, with the monotonic time it was
completed, on a :class:`~lost.host.live.backlog.Backlog` (a burst while a record is being navigated waits in memory,
not in the socket's buffer where the kernel would drop it unseen; the queue is bounded, its oldest value dropped and
counted when it is full, so the receiving thread never waits). The main thread takes pings off the queue through the
:class:`~lost.host.live.reorder.PingReorder` (back into time order) into the
:class:`~lost.host.live.navigator.LiveNavigator`, and the vehicle's DVL velocities and depth readings into it as
they come; each record's estimates go to the :class:`UdpSender` and the :class:`RunLog` as soon as they are made.
Fixes and headings from NMEA are counted (the navigation of a hull-mounted survey takes the ping's own position, as
the batch path does); USBL fixes are logged as they come and given to the navigator (the fix of their record). With a device correlator behind a
:class:`~lost.host.live.fallback.FallbackBackend`, its switches to software and back are logged and said at once.

Every per-run store is bounded (:mod:`lost.host.live.stats`): histograms of latencies and errors, counters by kind.

Latency is measured from the completion of the ping that closed a record (the first ping of the next
interval: a record is known to be whole only then) to its estimates sent (``latency_ms``, the reorder hold
included), and from that ping's release by the reorder buffer (``navigation_ms``).

It stops on :meth:`LiveServer.stop`, on Ctrl-C or SIGTERM (both a normal end here: the last record is
closed, the summary written), or after ``idle_stop_s`` seconds without a value once one came.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from collections import Counter
from typing import TextIO

from ..io.survey import Ping
from .backlog import DEFAULT_MAX_VALUES, Backlog
from .fallback import FallbackBackend
from .inputs import DepthReading, DvlVelocity, UsblFix
from .navigator import LiveEstimate, LiveNavigator
from .nmea import HeadingFix, PositionFix
from .outputs import RunLog, UdpSender
from .receiver import UdpReceiver
from .reorder import PingReorder
from .stats import EstimatorStats, LogHistogram

__all__ = ["LiveServer"]


class LiveServer:
    """One `lost serve` run: receiver, navigator, outputs (see the module)."""

    def __init__(self, receiver: UdpReceiver, navigator: LiveNavigator, sender: UdpSender, log: RunLog, *, status_s: float = 5.0,
                 idle_stop_s: float = 0.0, reorder_lag_s: float = 0.5, reorder_hold_s: float = 0.05, status_stream: TextIO | None = None,
                 fallback: FallbackBackend | None = None, queue_max_values: int = DEFAULT_MAX_VALUES) -> None:
        self.receiver, self.navigator, self.sender, self.log = receiver, navigator, sender, log
        self.status_s, self.idle_stop_s = status_s, idle_stop_s
        self.status_stream = status_stream if status_stream is not None else sys.stderr
        self.counts: Counter[str] = Counter()
        # Bounded whatever the run's length: a histogram of latencies, per estimator counts and a histogram of errors.
        self.latency_ms = LogHistogram(low=0.01, high=1e7)  # the closing ping decoded -> its record served (the reorder hold included)
        self.navigation_ms = LogHistogram(low=0.01, high=1e7)  # the closing ping out of the reorder buffer -> its record served
        self.reorder = PingReorder(reorder_lag_s, self.counts, hold_s=reorder_hold_s)
        self.fallback = fallback  # the device correlator with software behind it (None: the backend named, alone)
        self.served: dict[str, EstimatorStats] = {}
        self.last_refusal = ""
        self.ended = "running"
        self._queue = Backlog(queue_max_values)
        self._stop = threading.Event()
        self._started = time.monotonic()

    def stop(self) -> None:
        self._stop.set()

    def run(self) -> dict:
        """Serve until stopped (see the module); the summary."""
        thread = threading.Thread(target=self.receiver.run, args=(lambda value: self._queue.put((time.monotonic(), value)),), daemon=True)
        thread.start()
        last_value = None
        next_status = time.monotonic() + self.status_s
        try:
            while not self._stop.is_set():
                # Wake for the reorder buffer's next due ping, not later than the status and idle checks need.
                item = self._queue.get(timeout=min(0.05, max(self.reorder.wait_s(time.monotonic()), 0.001)))
                if item is None:
                    self._navigate(self.reorder.expire(time.monotonic()))
                    if last_value is not None and self.idle_stop_s and time.monotonic() - last_value > self.idle_stop_s:
                        self.ended = f"no datagram for {self.idle_stop_s:g} s"
                        break
                else:
                    received, value = item
                    last_value = received
                    self.take(received, value)
                    self._navigate(self.reorder.expire(time.monotonic()))  # a busy stream: pings due by their hold go too
                if time.monotonic() >= next_status:
                    print(self.status_line(), file=self.status_stream, flush=True)
                    next_status = time.monotonic() + self.status_s
            else:
                self.ended = "stopped"
        except KeyboardInterrupt:
            self.ended = "interrupted (Ctrl-C or SIGTERM)"
        self.receiver.stop()
        thread.join(5.0)
        while (item := self._queue.get(timeout=0.0)) is not None:  # what was received before the stop, then the decoder's last values
            self.take(*item)
        self._navigate(self.reorder.finish())
        self._serve(self._guarded(self.navigator.finish), None, None)
        print(self.status_line(), file=self.status_stream, flush=True)
        return self.summary()

    def take(self, received: float, value) -> None:
        """One decoded value, completed at monotonic time ``received``: a ping into the navigation, a fix counted."""
        if isinstance(value, Ping):
            self._navigate(self.reorder.add(value, received, time.monotonic(), self.receiver.decoder.sequence(value)))
        elif isinstance(value, DvlVelocity | DepthReading):
            self.navigator.add_sensor(value)
        elif isinstance(value, UsblFix):
            self.counts["USBL fixes received"] += 1
            self.log.line({"usbl": {"time_utc_s": value.time_s, "lat_deg": value.lat_deg, "lon_deg": value.lon_deg, "depth_m": value.depth_m,
                                    "sxx_m2": value.sxx_m2, "syy_m2": value.syy_m2, "sxy_m2": value.sxy_m2}})
            self.navigator.add_sensor(value)
        elif isinstance(value, PositionFix):
            self.counts["NMEA position fixes (not used)"] += 1
        elif isinstance(value, HeadingFix):
            self.counts["NMEA headings (not used)"] += 1

    def _navigate(self, released: list[tuple[Ping, float]]) -> None:
        for ping, received in released:
            out_of_buffer = time.monotonic()
            self._serve(self._guarded(self.navigator.add, ping), received, out_of_buffer)

    def _guarded(self, step, *values) -> list[LiveEstimate]:
        """A ping or the end through the navigation; a ping it refuses (another ship's, say) is counted, never a stop."""
        try:
            return step(*values)
        except ValueError as error:
            self.counts[f"pings refused by the navigation ({type(error).__name__})"] += 1  # by kind: a bounded set of keys
            self.last_refusal = " ".join(str(error).split())[:200]
            return []

    def _serve(self, estimates: list[LiveEstimate], received: float | None, released: float | None) -> None:
        self._correlator_events()
        by_record: dict[int, list[LiveEstimate]] = {}
        for estimate in estimates:
            by_record.setdefault(estimate.record, []).append(estimate)
        for group in by_record.values():
            for estimate in group:
                self.sender.send(estimate)
            self.log.record(group)
            for e in group:
                self.served.setdefault(e.estimator, EstimatorStats()).add(e.usable, math.hypot(e.east_m - e.truth_east_m, e.north_m - e.truth_north_m))
            if received is not None and released is not None:
                now = time.monotonic()
                self.latency_ms.add((now - received) * 1e3)
                self.navigation_ms.add((now - released) * 1e3)

    def _correlator_events(self) -> None:
        """The device's switches to software and back: in the log (a line each) and said at once on the status stream."""
        if self.fallback is None:
            return
        for when, serving, reason in self.fallback.events():
            utc = time.time() - (time.monotonic() - when)
            self.log.line({"correlator": {"time_utc_s": utc, "serving": serving, "reason": reason}})
            print(f"lost serve: correlator now {serving}: {reason}", file=self.status_stream, flush=True)

    def _drops(self) -> dict[str, int]:
        counts = _copy(self.receiver.decoder.counts)
        drops = {reason: n for reason, n in counts.items() if any(w in reason for w in ("skipped", "lost", "dropped", "missing", "without"))}
        drops.update(self._queue.counts())
        drops.update({reason: n for reason, n in {**self.navigator.counts, **self.counts, **self.sender.counts}.items()
                      if any(w in reason for w in ("skipped", "refused", "silent", "without", "not sent", "late", "dropped"))})
        return drops

    def status_line(self) -> str:
        records = self.navigator.counts["records stepped"]
        elapsed = max(time.monotonic() - self._started, 1e-9)
        latency = f"{self.latency_ms.last:.0f} ms (max {self.latency_ms.max:.0f})" if self.latency_ms.count else "-"
        drops = ", ".join(f"{reason} {n}" for reason, n in sorted(self._drops().items())) or "none"
        usable = " ".join(f"{name} {100 * fraction:.0f}%" for name, fraction in self.usable_fractions().items())
        correlator = ""
        if self.fallback is not None:
            correlator = (f"; correlator {self.fallback.serving}" if self.fallback.on_device
                          else f"; correlator software ({self.fallback.device.name} not answering)")
        return (f"lost serve: {records} records ({records / elapsed:.2f}/s), {_copy(self.receiver.decoder.counts)['pings']} pings, "
                f"latency {latency}; usable {usable or '-'}{correlator}; drops: {drops}")

    def usable_fractions(self) -> dict[str, float]:
        return {name: stats.usable_fraction for name, stats in self.served.items()}

    def summary(self) -> dict:
        latency = self.latency_ms
        return {"ended": self.ended, "records": self.navigator.counts["records stepped"], "served_for_s": time.monotonic() - self._started,
                "latency_ms": {"count": latency.count, **({f"p{q}": latency.quantile(q / 100) for q in (50, 90, 99)} if latency.count else {}),
                               "max": latency.max if latency.count else None},
                "navigation_ms": ({f"p{q}": self.navigation_ms.quantile(q / 100) for q in (50, 90, 99)} | {"max": self.navigation_ms.max}
                                  if self.navigation_ms.count else {}),
                "queue": {"max_values": self._queue.max_values, "deepest": self._queue.deepest, **self._queue.counts()},
                "reorder_lag_s": self.reorder.lag_s, "reorder_hold_s": self.reorder.hold_s,
                "correlator": ({"device": self.fallback.device.name, "serving": self.fallback.serving, **self.fallback.counts,
                                "last_failure": self.fallback.last_failure or None} if self.fallback is not None else None),
                "methods": {name: stats.as_dict() for name, stats in self.served.items()}, "last_refusal": self.last_refusal or None,
                "received": dict(_copy(self.receiver.decoder.counts)), "navigation": dict(self.navigator.counts),
                "estimator_counts": self.navigator.estimator_counts(), "server": dict(self.counts),
                "outputs": {"addresses": [f"{h}:{p}" for h, p in self.sender.addresses], **self.sender.counts},
                "survey": {"first_ping_utc_s": self.navigator.recorder.epoch_s, "skipped": dict(self.navigator.recorder.skipped)}}


def _copy(counts: Counter) -> Counter:
    """A copy of a Counter the receiving thread may be adding to (a new key mid-copy: try again)."""
    while True:
        try:
            return Counter(dict(counts))
        except RuntimeError:
            continue
