"""The device correlator with the software one behind it: when the board (or the co-simulation) stops answering, the
record is correlated in software, and the device is tried again every ``retry_s`` seconds.

:class:`FallbackBackend` is a :class:`~lost.host.correlator.backends.Backend` over a device backend (``fpga``: the
board on its serial port; ``rtl``: the co-simulated device). A call the device cannot answer (the driver's
:class:`~lost.host.correlator.driver.DeviceTimeout` after its retries, any other
:class:`~lost.host.correlator.driver.DeviceError`, or an ``OSError`` of the port, a cable pulled) is answered by the
software correlator instead, and every call after it, until ``retry_s`` seconds have passed: then the device is asked
again (its port reopened), and used from then on if it answers. Every backend returns the golden model's integers,
so the navigation's answers are the same whichever one served a record, bit for bit.

Each switch is counted (:attr:`counts`) and kept as an event (:meth:`events`: the monotonic time, ``"software"`` or
the device's name, the reason) for the status line and the run's log. :func:`with_fallback` puts one in the
correlator registry under the device's name for the time of a run (the navigation asks for its backend by name).
"""

from __future__ import annotations

import contextlib
import time
from collections import Counter, deque
from collections.abc import Callable, Iterator

from ..correlator.backends import Backend, FunctionBackend, software_surface
from ..correlator.driver import DeviceError
from ..correlator.result import Outcome

__all__ = ["FallbackBackend", "with_fallback", "DEVICE_FAILURES"]

#: What ends a device call and sends the record to the software correlator.
DEVICE_FAILURES = (DeviceError, OSError)


class FallbackBackend(Backend):
    """``device``, or the software correlator while it does not answer (see the module)."""

    def __init__(self, device: Backend, *, retry_s: float = 30.0, clock: Callable[[], float] = time.monotonic) -> None:
        if not retry_s > 0:
            raise ValueError(f"retry_s must be a positive number of seconds, got {retry_s!r}")
        self.device, self.retry_s, self._clock = device, float(retry_s), clock
        self.name = device.name
        self._software = FunctionBackend("software", software_surface)
        self.on_device = True
        self._retry_at = 0.0
        self.counts: Counter[str] = Counter()
        self._events: deque[tuple[float, str, str]] = deque(maxlen=256)
        self.last_failure = ""

    @property
    def serving(self) -> str:
        """The backend answering now: the device's name or ``"software"``."""
        return self.device.name if self.on_device else "software"

    def run(self, terrain, patch, mask, mean_compensation, area, exclusion_radius, *, map_key=None) -> Outcome:
        if not self.on_device and self._clock() >= self._retry_at:
            self.counts["device retries"] += 1
            self.on_device = True
            try:
                outcome = self.device.run(terrain, patch, mask, mean_compensation, area, exclusion_radius, map_key=map_key)
            except DEVICE_FAILURES as error:
                self._fail(error, again=True)
            else:
                self.counts["device back"] += 1
                self._events.append((self._clock(), self.device.name, "the device answers again"))
                self.counts["correlations on the device"] += 1
                return outcome
        if self.on_device:
            try:
                outcome = self.device.run(terrain, patch, mask, mean_compensation, area, exclusion_radius, map_key=map_key)
            except DEVICE_FAILURES as error:
                self._fail(error, again=False)
            else:
                self.counts["correlations on the device"] += 1
                return outcome
        self.counts["correlations in software (the device not answering)"] += 1
        return self._software.run(terrain, patch, mask, mean_compensation, area, exclusion_radius, map_key=map_key)

    def _fail(self, error: BaseException, *, again: bool) -> None:
        self.on_device = False
        self._retry_at = self._clock() + self.retry_s
        self.last_failure = f"{type(error).__name__}: {' '.join(str(error).split())[:200]}"
        with contextlib.suppress(*DEVICE_FAILURES):
            self.device.close()  # the port is reopened at the next try: a board replugged gets a fresh link
        if again:
            self.counts["device retries unanswered"] += 1
        else:
            self.counts["device stopped answering"] += 1
            self._events.append((self._clock(), "software", f"{self.device.name} not answering ({self.last_failure}); "
                                                             f"software until it does, tried every {self.retry_s:g} s"))

    def events(self) -> list[tuple[float, str, str]]:
        """The switches since the last call (monotonic time, the backend now serving, why), oldest first."""
        out = list(self._events)
        self._events.clear()
        return out

    def close(self) -> None:
        self.device.close()


@contextlib.contextmanager
def with_fallback(name: str, *, retry_s: float = 30.0, clock: Callable[[], float] = time.monotonic) -> Iterator[FallbackBackend]:
    """The registry's backend ``name`` (a device: ``fpga``, ``rtl``) behind a :class:`FallbackBackend` for the block's time."""
    from ..correlator import BACKENDS

    device = BACKENDS[name]
    fallback = FallbackBackend(device, retry_s=retry_s, clock=clock)
    BACKENDS[name] = fallback
    try:
        yield fallback
    finally:
        BACKENDS[name] = device
