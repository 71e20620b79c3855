"""Sensors on serial ports: NMEA, PD6 or JSON lines read with pyserial, split into lines and decoded as the UDP path does.

Each ``[[serial]]`` table of the settings (:class:`SerialSettings`) names a port by pyserial URL (a device path such
as ``/dev/ttyUSB0`` or ``/dev/serial/by-id/...``, or ``socket://``, ``rfc2217://``, ``loop://``), its baud rate and
the kind of line it carries. A :class:`SerialReader` reads it on a thread of its own, splits the bytes into lines
(CR LF or LF; a line may come in pieces), and hands each line whole to the receiver's
:class:`~lost.host.live.receiver.LiveDecoder` (the same checks and counters as a UDP datagram of that line).

Counted, never a stop (:attr:`LiveDecoder.counts`, names carrying the port's URL: a bounded set per port):

- a line not of the port's kind (an NMEA port sending a PD6 line, noise on the line);
- a line longer than :data:`MAX_LINE_BYTES` without an end (the baud rate wrong, say): dropped up to its end;
- the port gone (an ``OSError``: a USB adapter unplugged, a pty closed, a socket dropped): the part-line read
  before is dropped, the port closed and opened again every ``retry_s`` seconds until it opens;
- a port that does not open (at the start or after it went): tried again every ``retry_s``.
"""

from __future__ import annotations

import threading
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

from ..config import ConfigError, PositiveFloat

__all__ = ["SerialSettings", "SerialReader", "MAX_LINE_BYTES", "SERIAL_KINDS"]

#: A line's longest run of bytes without an end: NMEA's is 82, a PD6 line under 80, a JSON line of LOST's under 300.
MAX_LINE_BYTES = 4096
#: The kinds of line a port carries and the first character each starts with.
SERIAL_KINDS = {"nmea": b"$", "pd6": b":", "json": b"{"}
#: pyserial's URL schemes (``serial.serial_for_url``); a port without ``://`` is a device path.
_SCHEMES = ("loop", "socket", "rfc2217", "spy", "hwgrep", "alt", "cp2110")


@dataclass(frozen=True)
class SerialSettings:
    """One ``[[serial]]`` table: ``port`` (device path or pyserial URL), ``baud``, ``kind`` (nmea, pd6, json), ``retry_s``."""

    port: str
    kind: str
    baud: int = 9600
    retry_s: PositiveFloat = 2.0

    def __post_init__(self) -> None:
        if self.kind not in SERIAL_KINDS:
            raise ConfigError(f"[[serial]] kind must be one of {list(SERIAL_KINDS)}, got {self.kind!r}")
        if not self.port.strip():
            raise ConfigError("[[serial]] port must be a device path or a pyserial URL, got an empty string")
        scheme = self.port.partition("://")[0] if "://" in self.port else None
        if scheme is not None and scheme not in _SCHEMES:
            raise ConfigError(f"[[serial]] port {self.port!r}: pyserial knows no URL scheme {scheme!r} (known: {', '.join(_SCHEMES)})")
        if not 50 <= self.baud <= 4_000_000:
            raise ConfigError(f"[[serial]] baud must be a serial line's rate, 50 to 4000000, got {self.baud!r}")


def _open(settings: SerialSettings):
    import serial

    return serial.serial_for_url(settings.port, baudrate=settings.baud, timeout=0.1)


class SerialReader:
    """One serial port read on its own thread (see the module); ``feed`` gets each whole line, its end stripped.

    ``feed`` is called from this reader's thread: the receiver serializes it with its other inputs.
    """

    def __init__(self, settings: SerialSettings, feed: Callable[[bytes], None], counts: Counter,
                 opener: Callable[[SerialSettings], object] = _open) -> None:
        self.settings, self._feed, self.counts, self._opener = settings, feed, counts, opener
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._partial = bytearray()
        self._overlong = False  # dropping an overlong line up to its end
        self.opened = threading.Event()  # set each time the port opens (a test waits on it)

    def start(self) -> None:
        self._thread = threading.Thread(target=self.run, name=f"serial {self.settings.port}", daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = 2.0) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)

    def run(self) -> None:
        """Read until :meth:`stop`; a port gone or not opening is counted and tried again every ``retry_s``."""
        name, port = self.settings.port, None
        while not self._stop.is_set():
            if port is None:
                try:
                    port = self._opener(self.settings)
                except OSError:
                    self.counts[f"serial {name}: port did not open (tried again; its lines lost meanwhile)"] += 1
                    self._stop.wait(self.settings.retry_s)
                    continue
                self.counts[f"serial {name}: port opened"] += 1
                self.opened.set()
            try:
                chunk = port.read(max(1, port.in_waiting))
            except OSError:
                self.counts[f"serial {name}: port lost (OSError; opened again; its lines lost meanwhile)"] += 1
                if self._partial:
                    self.counts[f"serial {name}: part-line cut by the port's loss (skipped)"] += 1
                self._partial.clear()
                self._overlong = False
                _close(port)
                port = None
                self._stop.wait(self.settings.retry_s)
                continue
            if chunk:
                self._lines(chunk)
        if port is not None:
            _close(port)

    def _lines(self, chunk: bytes) -> None:
        name, start = self.settings.port, SERIAL_KINDS[self.settings.kind]
        *whole, rest = (bytes(self._partial) + chunk).split(b"\n")
        for k, line in enumerate(whole):
            if self._overlong and k == 0:  # the end of a line too long to keep
                self._overlong = False
                continue
            line = line.rstrip(b"\r")
            if not line.strip():
                continue
            if not line.startswith(start):
                self.counts[f"serial {name}: line not of the port's kind {self.settings.kind} (skipped)"] += 1
                continue
            self.counts[f"serial {name}: lines"] += 1
            self._feed(line + b"\r\n")
        self._partial = bytearray(rest)
        if len(self._partial) > MAX_LINE_BYTES:
            if not self._overlong:
                self.counts[f"serial {name}: line longer than {MAX_LINE_BYTES} bytes (skipped)"] += 1
            self._overlong = True
            self._partial.clear()


def _close(port) -> None:
    try:
        port.close()
    except OSError:
        pass
