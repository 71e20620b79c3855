"""An asynchronous serial receiver and transmitter (8N1), with byte streams.

amaranth-stdio's ``AsyncSerialRX``/``AsyncSerialTX`` give the shape (``divisor`` clocks per bit, a
data byte, ``rdy``/``ack``, a frame error); amaranth-stdio is not on PyPI, so these are our own, with
the byte side a :class:`lib.stream.Signature` like every other datapath boundary of the device.

Receiver: the line goes through a two-register synchronizer; a falling edge starts a character, whose
start bit is checked half a bit later (a glitch shorter than that is ignored) and whose data bits are
sampled at their middles, LSB first. A low stop bit is a frame error (the byte is dropped and
``frame_error`` pulses); a byte the stream has not taken when the next one completes is dropped and
``overrun`` pulses. The receiver never waits for its consumer.
"""

from typing import Any

from amaranth.hdl import Cat, Module, Signal
from amaranth.lib import stream, wiring
from amaranth.lib.cdc import FFSynchronizer
from amaranth.lib.wiring import In, Out

__all__ = ["AsyncSerialRX", "AsyncSerialTX"]


def _check_divisor(divisor: Any) -> int:
    if isinstance(divisor, bool) or not isinstance(divisor, int) or divisor < 4:
        raise ValueError(f"divisor (clocks per bit) must be an integer of at least 4, got {divisor!r}")
    return divisor


class AsyncSerialRX(wiring.Component):
    """8N1 receiver.

    Parameters
    ----------
    divisor : int
        Clocks per bit (clock frequency / baud rate), at least 4.

    Members
    -------
    rx : ``In(1)``
        The serial line (idle high); synchronized inside.
    data : ``Out(stream.Signature(8))``
        Received bytes; a byte waits in a one-byte register until taken.
    frame_error : ``Out(1)``
        Pulses when a character's stop bit is low.
    overrun : ``Out(1)``
        Pulses when a byte is dropped because the previous one was not taken.
    """

    rx: In(1, init=1)
    data: Out(stream.Signature(8))
    frame_error: Out(1)
    overrun: Out(1)

    def __init__(self, *, divisor: int):
        self._divisor = _check_divisor(divisor)
        super().__init__()

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        line = Signal(init=1)
        m.submodules.sync = FFSynchronizer(self.rx, line, init=1)

        timer = Signal(range(self._divisor))
        shift = Signal(8)
        bits = Signal(range(9))
        with m.If(self.data.ready):
            m.d.sync += self.data.valid.eq(0)

        with m.FSM():
            with m.State("IDLE"):
                with m.If(~line):
                    m.d.sync += timer.eq(self._divisor // 2 - 1)
                    m.next = "START"
            with m.State("START"):
                m.d.sync += timer.eq(timer - 1)
                with m.If(timer == 0):
                    with m.If(line):  # a glitch, not a start bit
                        m.next = "IDLE"
                    with m.Else():
                        m.d.sync += [timer.eq(self._divisor - 1), bits.eq(0)]
                        m.next = "DATA"
            with m.State("DATA"):
                m.d.sync += timer.eq(timer - 1)
                with m.If(timer == 0):
                    m.d.sync += [timer.eq(self._divisor - 1), shift.eq(Cat(shift[1:], line)), bits.eq(bits + 1)]
                    with m.If(bits == 7):
                        m.next = "STOP"
            with m.State("STOP"):
                m.d.sync += timer.eq(timer - 1)
                with m.If(timer == 0):
                    with m.If(~line):
                        m.d.comb += self.frame_error.eq(1)
                        m.next = "BREAK"
                    with m.Else():
                        with m.If(self.data.valid & ~self.data.ready):
                            m.d.comb += self.overrun.eq(1)
                        with m.Else():
                            m.d.sync += [self.data.payload.eq(shift), self.data.valid.eq(1)]
                        m.next = "IDLE"
            with m.State("BREAK"):  # wait for the line to go idle before hunting for a start bit
                with m.If(line):
                    m.next = "IDLE"
        return m


class AsyncSerialTX(wiring.Component):
    """8N1 transmitter.

    Parameters
    ----------
    divisor : int
        Clocks per bit, at least 4.

    Members
    -------
    data : ``In(stream.Signature(8))``
        Bytes to send; one is taken when the previous character's stop bit ends.
    tx : ``Out(1)``
        The serial line, a register (idle high).
    """

    data: In(stream.Signature(8))
    tx: Out(1, init=1)

    def __init__(self, *, divisor: int):
        self._divisor = _check_divisor(divisor)
        super().__init__()

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        timer = Signal(range(self._divisor))
        # Start bit, 8 data bits LSB first, stop bit, shifted out of one register; the eleventh bit
        # (also high) goes out when the stop bit has lasted a whole bit time, and ends the character.
        frame = Signal(11)
        left = Signal(range(12))
        with m.If(left == 0):
            m.d.comb += self.data.ready.eq(1)
            with m.If(self.data.valid):
                m.d.sync += [frame.eq(Cat(0, self.data.payload, 1, 1)), left.eq(11), timer.eq(0)]
        with m.Else():
            m.d.sync += timer.eq(timer - 1)
            with m.If(timer == 0):
                m.d.sync += [self.tx.eq(frame[0]), frame.eq(Cat(frame[1:], 1)), left.eq(left - 1),
                             timer.eq(self._divisor - 1)]
        return m
