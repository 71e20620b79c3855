# amaranth: UnusedElaboratable=no
"""The UART at bit level in the Amaranth simulator: every byte, baud error, glitches, frame errors, overrun."""

import itertools
import random

import pytest
from amaranth.hdl import Module
from amaranth.sim import Simulator

from lost.hdl.uart import AsyncSerialRX, AsyncSerialTX
from lost.sim.amaranth import drain, feed

DIVISOR = 8


async def send_bits(ctx, line, byte, *, bit_clocks=DIVISOR, stop=1):
    """Drive one 8N1 character on ``line``: start bit, data LSB first, stop bit, each ``bit_clocks`` clocks."""
    for bit in [0, *((byte >> k) & 1 for k in range(8)), stop]:
        ctx.set(line, bit)
        await ctx.tick().repeat(bit_clocks)
    ctx.set(line, 1)


async def receive_bits(ctx, line, *, bit_clocks=DIVISOR):
    """Wait for a start bit on ``line`` and decode one character at the bits' middles; (byte, stop bit)."""
    await ctx.tick().until(~line)
    await ctx.tick().repeat(bit_clocks // 2)
    assert not ctx.get(line), "the start bit ended early"
    byte = 0
    for k in range(8):
        await ctx.tick().repeat(bit_clocks)
        byte |= ctx.get(line) << k
    await ctx.tick().repeat(bit_clocks)
    return byte, ctx.get(line)


def _run(dut, *testbenches, clocks=40_000):
    """Run the testbenches for at most ``clocks`` clocks (a lost byte must fail, not hang)."""
    m = Module()
    m.submodules.dut = dut
    sim = Simulator(m)
    sim.add_clock(1e-8)
    for testbench in testbenches:
        sim.add_testbench(testbench)
    sim.run_until(clocks * 1e-8)


@pytest.mark.parametrize("bit_clocks", [DIVISOR, DIVISOR - 0.2, DIVISOR + 0.2])
def test_receiver_gets_every_byte_within_a_baud_error(bit_clocks):
    """All 256 bytes back to back, the sender's bit 2.5 % fast or slow (rounded per bit, so edges jitter)."""
    rx = AsyncSerialRX(divisor=DIVISOR)
    sent = list(range(256))
    received = []

    async def sender(ctx):
        elapsed = 0.0
        for byte in sent:
            for bit in [0, *((byte >> k) & 1 for k in range(8)), 1]:
                ctx.set(rx.rx, bit)
                clocks = round(elapsed + bit_clocks) - round(elapsed)
                elapsed += bit_clocks
                await ctx.tick().repeat(clocks)

    async def sink(ctx):
        received.extend(await drain(ctx, rx.data, len(sent)))

    _run(rx, sender, sink, clocks=25_000)
    assert received == sent


def test_a_glitch_is_no_start_bit_and_a_low_stop_bit_is_a_frame_error():
    rx = AsyncSerialRX(divisor=DIVISOR)
    errors, received = [], []

    async def sender(ctx):
        await ctx.tick().repeat(5)
        ctx.set(rx.rx, 0)  # shorter than half a bit
        await ctx.tick().repeat(2)
        ctx.set(rx.rx, 1)
        await ctx.tick().repeat(3 * DIVISOR)
        await send_bits(ctx, rx.rx, 0x3C, stop=0)  # framing error: dropped
        await ctx.tick().repeat(2 * DIVISOR)
        await send_bits(ctx, rx.rx, 0xA5)
        await ctx.tick().repeat(2 * DIVISOR)

    async def sink(ctx):
        received.extend(await drain(ctx, rx.data, 1))

    async def monitor(ctx):
        async for _, _, frame_error in ctx.tick().sample(rx.frame_error):
            errors.append(frame_error)

    m = Module()
    m.submodules.dut = rx
    sim = Simulator(m)
    sim.add_clock(1e-8)
    sim.add_testbench(sender)
    sim.add_testbench(sink)
    sim.add_testbench(monitor, background=True)
    sim.run_until(2e-5)
    assert received == [0xA5] and sum(errors) == 1


def test_an_untaken_byte_is_kept_and_the_next_one_is_an_overrun():
    rx = AsyncSerialRX(divisor=DIVISOR)
    overruns, received = [], []

    async def sender(ctx):
        for byte in (0x11, 0x22, 0x33):
            await send_bits(ctx, rx.rx, byte)
        received.extend(await drain(ctx, rx.data, 1))
        await send_bits(ctx, rx.rx, 0x44)
        received.extend(await drain(ctx, rx.data, 1))

    async def monitor(ctx):
        async for _, _, overrun in ctx.tick().sample(rx.overrun):
            overruns.append(overrun)

    m = Module()
    m.submodules.dut = rx
    sim = Simulator(m)
    sim.add_clock(1e-8)
    sim.add_testbench(sender)
    sim.add_testbench(monitor, background=True)
    sim.run_until(2e-5)
    assert received == [0x11, 0x44] and sum(overruns) == 2


def test_transmitter_sends_every_byte_with_a_whole_stop_bit_under_random_gaps():
    tx = AsyncSerialTX(divisor=DIVISOR)
    rng = random.Random(3)
    sent = [rng.randrange(256) for _ in range(40)]
    received = []

    async def source(ctx):
        await feed(ctx, tx.data, sent, pattern=itertools.cycle([1, 1, 0, 1, 0, 0, 0]))

    async def line(ctx):
        for _ in sent:
            byte, stop = await receive_bits(ctx, tx.tx)
            assert stop == 1
            # The stop bit lasts until the next start bit, at least a whole bit.
            assert all([ctx.get(tx.tx) for _ in [await ctx.tick().repeat(DIVISOR // 2 - 1)]])
            received.append(byte)

    _run(tx, source, line)
    assert received == sent


def test_transmitter_into_receiver_loops_back():
    tx, rx = AsyncSerialTX(divisor=5), AsyncSerialRX(divisor=5)
    m = Module()
    m.submodules.tx, m.submodules.rx = tx, rx
    m.d.comb += rx.rx.eq(tx.tx)
    sent = list(range(0, 256, 7))
    received = []

    async def source(ctx):
        await feed(ctx, tx.data, sent)

    async def sink(ctx):
        received.extend(await drain(ctx, rx.data, len(sent), pattern=itertools.cycle([1, 0, 0])))

    sim = Simulator(m)
    sim.add_clock(1e-8)
    sim.add_testbench(source)
    sim.add_testbench(sink)
    sim.run_until(2e-5)
    assert received == sent


def test_a_divisor_below_four_is_refused():
    with pytest.raises(ValueError, match="at least 4"):
        AsyncSerialRX(divisor=3)
