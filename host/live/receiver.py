"""The receiving side: UDP datagrams in, pings and fixes out, every fault counted and none a stop.

:class:`LiveDecoder` takes one datagram's bytes at a time (from a socket, or from anything) and returns what it
completed: :class:`~lost.host.io.survey.Ping` values (raw: latitude/longitude, no projection yet, as the file
readers yield them before :class:`~lost.host.io.survey.Survey` projects them), :class:`~lost.host.live.nmea.PositionFix`
and :class:`~lost.host.live.nmea.HeadingFix`. A datagram is ``.kmall`` when its first four bytes are its own
length and the next a ``#`` and three capitals, NMEA when it starts with ``$``.

- ``#MRZ`` is decoded by pykmall, as :mod:`lost.host.io.kmall` decodes a file's, its attitude interpolated from the
  ``#SKM`` samples received before it (the last :data:`ATTITUDE_SAMPLES`); partitions (``numOfDgms`` > 1) are joined
  by the file reader's rule (:class:`lost.host.io.kmall_parts.MrzJoiner`: in ``dgmNum`` order whatever order they
  come in; a ping whose parts are not all in while :data:`PENDING_PINGS` later pings begin, or at
  :meth:`~LiveDecoder.finish`, dropped and counted; two partitioned MRZ of one time, two heads, dropped and counted);
- a datagram or a part seen before (the same bytes, among the last few thousand) is counted and skipped;
- a datagram whose length fields disagree with its size, or that pykmall cannot decode, is counted and skipped;
- a ping whose #MRZ never came whole shows as a gap in the MRZ ping counter, counted at the end;
- a ping decoded without attitude after #SKM samples were received (its own sample late or lost) is counted;
- NMEA sentences through :class:`~lost.host.live.nmea.NmeaDecoder` (checksums checked, bad ones counted), a USBL's
  ``$PSONLLD``/``$PSIMSSB`` among them (``usbl_default_sigma_m``: the 1 sigma of a fix whose sentence has no error
  fields; None refuses those, :mod:`lost.host.live.usbl_nmea`).

:class:`UdpReceiver` binds a socket and feeds a decoder until stopped.
"""

from __future__ import annotations

import contextlib
import io
import selectors
import socket
import struct
import threading
from collections import Counter, OrderedDict, deque

import numpy as np

from ..io.kmall import decode_mrz, mrz_ping
from ..io.kmall_parts import PENDING_PINGS, MrzJoiner
from ..io.survey import Ping
from .inputs import JsonInputDecoder, Pd6Decoder
from .nmea import NmeaDecoder, PositionFix
from .serial import SerialReader, SerialSettings

__all__ = ["LiveDecoder", "UdpReceiver", "ATTITUDE_SAMPLES", "PENDING_PINGS"]

ATTITUDE_SAMPLES = 4096
_RECENT_KEYS = 4096
# The .kmall datagram kinds counted by name; any other is counted as "other" (a bounded set of counters whatever arrives).
_KMALL_KINDS = frozenset({"#IIP", "#IOP", "#IBE", "#IBR", "#IBS", "#MRZ", "#MWC", "#SPO", "#SKM", "#SVP", "#SVT", "#SCL", "#SDE", "#SHI",
                          "#SHA", "#CPO", "#CHE", "#FCF"})
_HEADER = struct.Struct("<I4sBBHII")


class LiveDecoder:
    """Datagrams in, pings and fixes out (see the module); ``counts`` holds reason -> count."""

    def __init__(self, usbl_default_sigma_m: float | None = None) -> None:
        self.counts: Counter[str] = Counter()
        self._nmea = NmeaDecoder(self.counts, usbl_default_sigma_m)
        self._pd6 = Pd6Decoder(self.counts)
        self._json = JsonInputDecoder(self.counts)
        self._attitude: deque[tuple[float, float, float, float]] = deque(maxlen=ATTITUDE_SAMPLES)
        self._joiner = MrzJoiner(self.counts)
        self._seen: OrderedDict[int, None] = OrderedDict()
        # The MRZ ping counters, unwrapped past 65,535: first, highest, how many distinct, the recent ones (bounded memory).
        self._counter_span: list[int] | None = None
        self._counters_received = 0
        self._recent_counters: OrderedDict[int, None] = OrderedDict()
        self._sequence: OrderedDict[tuple[float, int], int] = OrderedDict()  # (time, head) -> counter, read by the reorder buffer

    def feed(self, payload: bytes) -> list:
        """What this datagram completes (often nothing); never raises on bad bytes."""
        lines = {b"$": self._nmea, b":": self._pd6, b"{": self._json}.get(payload[:1])
        if lines is not None:
            out: list = []
            for line in payload.decode("utf-8", errors="replace").splitlines():
                if line.strip():
                    out += lines.feed(line)
            return out
        if len(payload) >= _HEADER.size + 4 and payload[4:5] == b"#" and payload[5:8].isalpha() and payload[5:8].isupper():
            return self._kmall(payload)
        self.counts["datagram of neither .kmall, NMEA, PD6 nor JSON (skipped)"] += 1
        return []

    def finish(self) -> list[Ping | PositionFix]:
        """The end of the stream: the fix held for its VTG; pings still missing parts are counted as lost, so are gaps in the ping counter."""
        self._joiner.finish()
        if self._counter_span:
            missing = self._counter_span[1] - self._counter_span[0] + 1 - self._counters_received
            if missing > 0:
                self.counts["pings missing from the ping counter's sequence"] += missing
        return list(self._nmea.flush())

    def _kmall(self, payload: bytes) -> list[Ping]:
        size, kind, _, _, _, time_sec, time_nanosec = _HEADER.unpack_from(payload)
        name = kind.decode("ascii") if kind.decode("ascii") in _KMALL_KINDS else "(other kind)"
        if size != len(payload) or int.from_bytes(payload[-4:], "little") != size:
            self.counts[f"kmall {name} datagram whose length fields disagree with its size (skipped)"] += 1
            return []
        if self._already_seen(hash(payload)):
            self.counts["duplicate kmall datagram (skipped)"] += 1
            return []
        self.counts[f"kmall {name} datagrams"] += 1
        if time_nanosec < 1_000_000_000:  # the sonar's clock: dates a vendor USBL fix when no ZDA has come
            self.sonar_clock(time_sec + time_nanosec * 1e-9)
        if name == "#SKM":
            self._skm(payload)
            return []
        if name != "#MRZ":
            return []
        whole = self._joiner.add(payload)  # the file reader's rule for partitions (lost.host.io.kmall_parts)
        return [] if whole is None else self._decoded(whole)

    def _already_seen(self, key: int) -> bool:
        if key in self._seen:
            return True
        self._seen[key] = None
        if len(self._seen) > _RECENT_KEYS:
            self._seen.popitem(last=False)
        return False

    def _skm(self, payload: bytes) -> None:
        reader = _reader(payload)
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                samples = reader.read_EMdgmSKM()["sample"]["KMdefault"]
            rows = [tuple(float(v) for v in sample)
                    for sample in zip(samples["dgtime"], samples["roll_deg"], samples["pitch_deg"], samples["heave_m"], strict=True)]
        except (struct.error, KeyError, ValueError, IndexError, TypeError, UnicodeDecodeError):  # pykmall on garbage: any of these
            self.counts["kmall #SKM that does not decode (skipped)"] += 1
            return
        self._attitude.extend(rows)

    def _decoded(self, datagram: bytes) -> list[Ping]:
        try:
            dg = decode_mrz(datagram)
            ping = mrz_ping(dg, self._attitude_arrays())
        except (struct.error, KeyError, ValueError, IndexError, TypeError, UnicodeDecodeError) as error:
            self.counts[f"kmall #MRZ that does not decode ({type(error).__name__}; skipped)"] += 1
            return []
        self.counts["pings"] += 1
        counter = self._count_ping(int(dg["cmnPart"]["pingCnt"]))
        self._sequence[(ping.time_s, ping.head)] = counter
        if len(self._sequence) > _RECENT_KEYS:
            self._sequence.popitem(last=False)
        if self._attitude and not np.isfinite(ping.roll_deg):
            self.counts["ping without attitude at its time (its #SKM late or lost)"] += 1
        return [ping]

    def sonar_clock(self, time_s: float) -> None:
        """Set the sonar's clock (POSIX seconds), as a ``.kmall`` datagram of that time would: it dates vendor USBL fixes until a ZDA comes."""
        self._nmea.sonar_time_s = time_s

    def sequence(self, ping: Ping) -> int | None:
        """The MRZ ping counter of a ping this decoder made (unwrapped past 65,535), among its last 4,096; None if not."""
        return self._sequence.get((ping.time_s, ping.head))

    def _count_ping(self, counter: int) -> int:
        if self._counter_span is None:
            self._counter_span = [counter, counter]
        else:
            counter += (self._counter_span[1] - counter + 32_768) // 65_536 * 65_536  # the unwrapped value nearest the highest
            self._counter_span = [min(self._counter_span[0], counter), max(self._counter_span[1], counter)]
        if counter not in self._recent_counters:
            self._counters_received += 1
            self._recent_counters[counter] = None
            if len(self._recent_counters) > _RECENT_KEYS:
                self._recent_counters.popitem(last=False)
        return counter

    def _attitude_arrays(self) -> dict[str, np.ndarray]:
        table = np.array(self._attitude, dtype=np.float64).reshape(-1, 4)
        order = np.argsort(table[:, 0], kind="stable")
        return {name: table[order, k] for k, name in enumerate(("t", "roll", "pitch", "heave"))}


def _reader(datagram: bytes):
    from KMALL.kmall import kmall

    reader = kmall(None)
    reader.FID = io.BytesIO(datagram)
    reader.file_size = len(datagram)
    return reader


class UdpReceiver:
    """UDP sockets on ``(host, port)`` and on each of ``more`` (port 0: any free one, see :attr:`addresses`) feeding one
    :class:`LiveDecoder`: every port takes every kind, told by its content (.kmall, NMEA, PD6, JSON lines).
    Each of ``serial`` (:class:`~lost.host.live.serial.SerialSettings`) is read on a thread of its own into the same
    decoder, a line at a time (:mod:`lost.host.live.serial`); the decoder is fed by one input at a time.

    :meth:`run` receives until :meth:`stop`; each completed value goes to ``on_value``. Each socket asks for a
    receive buffer of ``buffer_bytes`` (the system may give less: bursts beyond it are lost by the kernel,
    uncounted here, and show as missing pings).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, *, more: tuple[tuple[str, int], ...] = (), buffer_bytes: int = 4 << 20,
                 serial: tuple[SerialSettings, ...] = (), usbl_default_sigma_m: float | None = None) -> None:
        self.decoder = LiveDecoder(usbl_default_sigma_m)
        self.serial = serial
        self._feeding = threading.Lock()  # the decoder's state is one: a UDP datagram and a serial line are decoded in turn
        self.socks: list[socket.socket] = []
        try:
            for where in ((host, port), *more):
                self.socks.append(_bound(where, buffer_bytes))
        except OSError:
            for sock in self.socks:
                sock.close()
            raise
        self.sock = self.socks[0]
        self.addresses: list[tuple[str, int]] = [sock.getsockname() for sock in self.socks]
        self.address: tuple[str, int] = self.addresses[0]
        self._stop = threading.Event()
        self.serial_readers: list[SerialReader] = []

    def run(self, on_value) -> None:
        """Receive and decode until :meth:`stop`; then the decoder's :meth:`~LiveDecoder.finish`, and the sockets closed."""
        selector = selectors.DefaultSelector()
        for sock in self.socks:
            selector.register(sock, selectors.EVENT_READ)
        readers = [SerialReader(settings, lambda line: self._feed(line, on_value), self.decoder.counts) for settings in self.serial]
        self.serial_readers = readers
        for reader in readers:
            reader.start()
        try:
            while True:
                ready = selector.select(timeout=0.05)
                if not ready and self._stop.is_set():
                    break
                for key, _ in ready:
                    try:
                        payload = key.fileobj.recv(65_535)
                    except BlockingIOError:
                        continue
                    self._feed(payload, on_value)
            for reader in readers:
                reader.stop()
            with self._feeding:
                for value in self.decoder.finish():
                    on_value(value)
        finally:
            for reader in readers:
                reader.stop()
            selector.close()
            for sock in self.socks:
                sock.close()

    def _feed(self, payload: bytes, on_value) -> None:
        with self._feeding:
            for value in self.decoder.feed(payload):
                on_value(value)

    def stop(self) -> None:
        """Stop once the datagrams already received are read."""
        self._stop.set()


def _bound(where: tuple[str, int], buffer_bytes: int) -> socket.socket:
    host, port = where
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    with contextlib.suppress(OSError):
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, buffer_bytes)
    try:
        sock.bind((host, port))
    except OSError as error:
        sock.close()
        raise OSError(error.errno, f"cannot listen on {host}:{port} for UDP datagrams: {error.strerror or error}") from None
    sock.setblocking(False)
    return sock
