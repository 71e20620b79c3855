# amaranth: UnusedElaboratable=no
"""The frame receiver and sender against lost.model.protocol, at byte-stream level in the Amaranth simulator."""

import itertools
import random

from amaranth.hdl import Module
from amaranth.lib import memory, wiring
from amaranth.sim import Simulator

from lost.hdl.link import FrameReceiver, FrameSender
from lost.model.protocol import MAX_PAYLOAD, ErrorCode, FrameDecoder, crc16, encode_frame
from lost.sim.amaranth import drain, feed

TIMEOUT = 50


def _receive(stream_bytes, *, gaps=()):
    """Feed bytes (``None`` = that many idle clocks, as ``("gap", n)``) to a receiver; return requests with payloads."""
    receiver = FrameReceiver(timeout=TIMEOUT)
    m = Module()
    m.submodules.receiver = receiver
    m.submodules.buffer = buffer = memory.Memory(shape=8, depth=MAX_PAYLOAD, init=[])
    wiring.connect(m, receiver.buffer, buffer.write_port())
    read = buffer.read_port(domain="comb")
    requests = []

    async def source(ctx):
        for item in stream_bytes:
            if isinstance(item, tuple):
                await ctx.tick().repeat(item[1])
            else:
                await feed(ctx, receiver.bytes_in, [item])
        await ctx.tick().repeat(TIMEOUT + 10)

    async def sink(ctx):
        while True:
            (request,) = await drain(ctx, receiver.request, 1, pattern=itertools.cycle([1, 0]))
            data = []
            for k in range(request["length"] if request["error"] == 0 else 0):
                ctx.set(read.addr, k)
                data.append(ctx.get(read.data))
            requests.append((request["error"], request["seq"], request["command"], bytes(data)))

    sim = Simulator(m)
    sim.add_clock(1e-8)
    sim.add_testbench(source)
    sim.add_testbench(sink, background=True)
    sim.run()
    return requests


def test_good_frames_between_garbage_arrive_with_their_payloads():
    rng = random.Random(1)
    frames = [(rng.randrange(256), rng.randrange(256), bytes(rng.randrange(256) for _ in range(n))) for n in (0, 1, 7, 300)]
    stream = []
    for seq, command, payload in frames:
        stream += [0x00, 0x5A, 0xFF] + list(encode_frame(seq, command, payload))
    assert _receive(stream) == [(0, seq, command, payload) for seq, command, payload in frames]


def test_bad_crc_oversized_and_truncated_frames_are_refused_and_the_next_one_works():
    good = list(encode_frame(9, 0x01, b"ok"))
    bad_crc = list(encode_frame(3, 0x02, b"abc"))
    bad_crc[-1] ^= 1
    oversized = [0xA5, 4, 0x02, 0x01, 0x04]  # 1025 bytes announced
    truncated = list(encode_frame(5, 0x03, b"0123456789"))[:9]
    stream = bad_crc + good + oversized + good + truncated + [("gap", TIMEOUT + 5)] + good
    got = _receive(stream)
    assert got == [
        (ErrorCode.CRC, 3, 0x02, b""), (0, 9, 0x01, b"ok"),
        (ErrorCode.LENGTH, 4, 0x02, b""), (0, 9, 0x01, b"ok"),
        (ErrorCode.TIMEOUT, 5, 0x03, b""), (0, 9, 0x01, b"ok"),
    ]


def test_a_slow_but_steady_frame_is_no_timeout():
    frame = encode_frame(7, 0x04, bytes(range(20)))
    stream = [item for byte in frame for item in (byte, ("gap", TIMEOUT - 3))]
    assert _receive(stream) == [(0, 7, 0x04, bytes(range(20)))]


def test_the_sender_frames_every_reply_as_the_reference_encoder():
    sender = FrameSender()
    rng = random.Random(2)
    replies = [(rng.randrange(256), rng.randrange(256), bytes(rng.randrange(256) for _ in range(n))) for n in (0, 3, 260)]
    expected = b"".join(encode_frame(*reply) for reply in replies)
    received = []

    async def source(ctx):
        for seq, command, payload in replies:
            await feed(ctx, sender.header, [{"seq": seq, "command": command, "length": len(payload)}])
            await feed(ctx, sender.payload, list(payload), pattern=itertools.cycle([1, 0, 1]))

    async def sink(ctx):
        received.extend(await drain(ctx, sender.bytes_out, len(expected), pattern=itertools.cycle([1, 1, 0])))

    sim = Simulator(sender)
    sim.add_clock(1e-8)
    sim.add_testbench(source)
    sim.add_testbench(sink)
    sim.run()
    assert bytes(received) == expected
    assert FrameDecoder().feed(bytes(received))[2].payload == replies[2][2]
    assert crc16(b"123456789") == 0x29B1
