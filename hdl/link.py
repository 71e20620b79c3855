"""The device's framing: a frame receiver into a payload buffer and a frame sender, with CRC-16.

The frame format, the command bytes and the error codes are :mod:`lost.model.protocol`; the
receiver behaves as its :class:`~lost.model.protocol.FrameDecoder` does, plus a frame timeout:

* outside a frame, every byte but ``SYNC`` is dropped (resynchronization after garbage);
* a length above ``MAX_PAYLOAD`` ends the frame at once with a LENGTH error;
* a frame whose next byte does not arrive within ``timeout`` clocks is dropped with a TIMEOUT error
  (a truncated frame never wedges the receiver);
* a CRC mismatch drops the frame with a CRC error; nothing of it is executed.

A good frame's payload is in the buffer (a :class:`lib.memory.Memory` of ``MAX_PAYLOAD`` bytes the
caller owns) when its :class:`Request` beat is offered. The receiver takes no byte while ``hold`` is
high (the caller reads the buffer) or while its request waits to be taken (the buffer holds that
frame); the UART keeps one byte meanwhile and drops later ones (an overrun). So one frame is received
while the previous one executes.
"""

from typing import Any

from amaranth.hdl import Cat, Module, Mux, Signal, Value
from amaranth.lib import data, memory, stream, wiring
from amaranth.lib.wiring import In, Out
from amaranth.utils import bits_for

from lost.model.protocol import MAX_PAYLOAD, MAX_REPLY, SYNC, ErrorCode

__all__ = ["FrameReceiver", "FrameSender", "Request", "ReplyHeader", "crc16_update"]

#: A received frame (``error == 0``) or a refused one (its ErrorCode), with what was read of its header.
Request = data.StructLayout({
    "seq": 8,
    "command": 8,
    "length": bits_for(MAX_PAYLOAD),
    "error": 3,
})

#: The header of a reply; its payload follows on the sender's ``payload`` stream.
ReplyHeader = data.StructLayout({"seq": 8, "command": 8, "length": bits_for(MAX_REPLY)})


def crc16_update(crc: Value, byte: Value) -> Value:
    """CRC-16/CCITT-FALSE of ``crc`` after one more ``byte`` (polynomial 0x1021, MSB first), combinational."""
    for k in range(8):
        feedback = crc[15] ^ byte[7 - k]
        crc = (crc << 1)[:16] ^ Mux(feedback, 0x1021, 0)
    return crc


class FrameReceiver(wiring.Component):
    """Bytes in, requests out; payload bytes written to the caller's buffer.

    Parameters
    ----------
    timeout : int
        Clocks without a byte after which a partial frame is dropped (TIMEOUT).

    Members
    -------
    bytes_in : ``In(stream.Signature(8))``
        From the UART receiver; taken unless ``hold`` or a request waits.
    request : ``Out(stream.Signature(Request))``
        One beat per frame (good or refused), held until taken.
    buffer : ``In(memory.WritePort.Signature(addr_width=..., shape=8))``
        Where payload byte ``k`` is written, at address ``k``.
    hold : ``In(1)``
        Take no byte while high (the caller is reading the buffer).
    """

    def __init__(self, *, timeout: int):
        if isinstance(timeout, bool) or not isinstance(timeout, int) or timeout < 2:
            raise ValueError(f"timeout must be an integer number of clocks of at least 2, got {timeout!r}")
        self._timeout = timeout
        super().__init__({
            "bytes_in": In(stream.Signature(8)),
            "request": Out(stream.Signature(Request)),
            "buffer": In(memory.WritePort.Signature(addr_width=bits_for(MAX_PAYLOAD - 1), shape=8)),
            "hold": In(1),
        })

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        byte = self.bytes_in.payload
        got = Signal()
        # Stalled while the caller reads the buffer or the last request waits: the UART holds one byte.
        m.d.comb += [self.bytes_in.ready.eq(~self.hold & ~self.request.valid), got.eq(self.bytes_in.valid & self.bytes_in.ready)]

        header = Signal(Request)
        crc = Signal(16, init=0xFFFF)
        received_crc = Signal(8)
        index = Signal(range(MAX_PAYLOAD + 1))
        idle = Signal(range(self._timeout + 1))
        timed_out = Signal()
        m.d.comb += timed_out.eq((idle == self._timeout) & ~got)

        with m.If(self.request.ready):
            m.d.sync += self.request.valid.eq(0)

        def finish(error):
            m.d.sync += [self.request.valid.eq(1), self.request.payload.eq(header), self.request.payload.error.eq(error)]
            m.next = "HUNT"

        def expire():
            """A partial frame whose next byte is overdue ends with TIMEOUT."""
            with m.If(timed_out):
                finish(ErrorCode.TIMEOUT)

        with m.FSM() as fsm:
            with m.State("HUNT"):
                with m.If(got & (byte == SYNC)):
                    m.d.sync += [crc.eq(0xFFFF), index.eq(0), header.eq(0)]
                    m.next = "SEQ"
            for state, field, following in (("SEQ", "seq", "COMMAND"), ("COMMAND", "command", "LENGTH_LO")):
                with m.State(state):
                    expire()
                    with m.If(got):
                        m.d.sync += [getattr(header, field).eq(byte), crc.eq(crc16_update(crc, byte))]
                        m.next = following
            with m.State("LENGTH_LO"):
                expire()
                with m.If(got):
                    m.d.sync += [header.length.eq(byte), crc.eq(crc16_update(crc, byte))]
                    m.next = "LENGTH_HI"
            with m.State("LENGTH_HI"):
                expire()
                with m.If(got):
                    length = Cat(header.length[:8], byte)
                    m.d.sync += [header.length.eq(length), crc.eq(crc16_update(crc, byte))]
                    with m.If(length > MAX_PAYLOAD):
                        finish(ErrorCode.LENGTH)
                    with m.Elif(length == 0):
                        m.next = "CRC_LO"
                    with m.Else():
                        m.next = "PAYLOAD"
            with m.State("PAYLOAD"):
                expire()
                m.d.comb += [self.buffer.addr.eq(index), self.buffer.data.eq(byte), self.buffer.en.eq(got)]
                with m.If(got):
                    m.d.sync += [index.eq(index + 1), crc.eq(crc16_update(crc, byte))]
                    with m.If(index + 1 == header.length):
                        m.next = "CRC_LO"
            with m.State("CRC_LO"):
                expire()
                with m.If(got):
                    m.d.sync += received_crc.eq(byte)
                    m.next = "CRC_HI"
            with m.State("CRC_HI"):
                expire()
                with m.If(got):
                    finish(Mux(Cat(received_crc, byte) == crc, 0, ErrorCode.CRC))

        # The frame timeout: clocks since the last byte of a partial frame.
        with m.If(fsm.ongoing("HUNT") | got | timed_out):
            m.d.sync += idle.eq(0)
        with m.Else():
            m.d.sync += idle.eq(idle + 1)
        return m


class FrameSender(wiring.Component):
    """A reply frame: header beat in, then its payload bytes, out as bytes with the CRC appended.

    Members
    -------
    header : ``In(stream.Signature(ReplyHeader))``
        Taken when the previous frame's last byte was sent.
    payload : ``In(stream.Signature(8))``
        Exactly ``length`` bytes for each header.
    bytes_out : ``Out(stream.Signature(8))``
        To the UART transmitter.
    idle : ``Out(1)``
        No frame under way.
    """

    header: In(stream.Signature(ReplyHeader))
    payload: In(stream.Signature(8))
    bytes_out: Out(stream.Signature(8))
    idle: Out(1)

    def elaborate(self, platform: Any) -> Module:
        m = Module()
        frame = Signal(ReplyHeader)
        crc = Signal(16)
        sent = Signal(range(MAX_REPLY + 1))
        out = self.bytes_out
        moved = out.valid & out.ready
        length_hi = Signal(8)
        m.d.comb += length_hi.eq(frame.length[8:])

        def emit(value, next_state, *, checked=True):
            m.d.comb += [out.valid.eq(1), out.payload.eq(value)]
            with m.If(out.ready):
                if checked:
                    m.d.sync += crc.eq(crc16_update(crc, value))
                m.next = next_state

        with m.FSM():
            with m.State("IDLE"):
                m.d.comb += [self.idle.eq(1), self.header.ready.eq(1)]
                with m.If(self.header.valid):
                    m.d.sync += [frame.eq(self.header.payload), crc.eq(0xFFFF), sent.eq(0)]
                    m.next = "SYNC"
            with m.State("SYNC"):
                emit(SYNC, "SEQ", checked=False)
            with m.State("SEQ"):
                emit(frame.seq, "COMMAND")
            with m.State("COMMAND"):
                emit(frame.command, "LENGTH_LO")
            with m.State("LENGTH_LO"):
                emit(frame.length[:8], "LENGTH_HI")
            with m.State("LENGTH_HI"):
                emit(length_hi, "PAYLOAD_OR_CRC")
            with m.State("PAYLOAD_OR_CRC"):
                with m.If(sent == frame.length):
                    m.next = "CRC_LO"
                with m.Else():
                    m.d.comb += [out.valid.eq(self.payload.valid), out.payload.eq(self.payload.payload),
                                 self.payload.ready.eq(out.ready)]
                    with m.If(moved):
                        m.d.sync += [crc.eq(crc16_update(crc, self.payload.payload)), sent.eq(sent + 1)]
            with m.State("CRC_LO"):
                emit(crc[:8], "CRC_HI", checked=False)
            with m.State("CRC_HI"):
                emit(crc[8:], "IDLE", checked=False)
        return m
