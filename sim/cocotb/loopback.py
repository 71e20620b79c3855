"""The harness proving itself: a one-register stream, its Verilog on Verilator, and three cocotb tests.

:class:`Loopback` forwards a struct payload (signed, one-bit and array fields) through one register,
so each beat leaves exactly one clock after it entered when the sink is always ready. The tests check
the parts the correlator benches stand on: payload encoding and decoding from an Amaranth layout,
no loss or duplication under idle and back-pressure patterns, the cycle of every transfer, and a
synchronous reset in the middle of a stream.
"""

import random

import cocotb
from amaranth.hdl import Module, signed, unsigned
from amaranth.lib import data, stream, wiring
from amaranth.lib.wiring import In, Out
from cocotb.handle import HierarchyObject
from cocotb.triggers import ClockCycles, RisingEdge

from .streams import Clocking, StreamSink, StreamSource, pattern

__all__ = ["LOOPBACK_LAYOUT", "Loopback"]

LOOPBACK_LAYOUT = data.StructLayout(
    {"depth": signed(16), "valid": 1, "values": data.ArrayLayout(unsigned(30), 3), "last": 1}
)


class Loopback(wiring.Component):
    """A stream register: ``words_out`` is ``words_in`` one clock later, with full throughput.

    Members
    -------
    words_in : In(stream.Signature(LOOPBACK_LAYOUT))
    words_out : Out(stream.Signature(LOOPBACK_LAYOUT))
    """

    words_in: In(stream.Signature(LOOPBACK_LAYOUT))
    words_out: Out(stream.Signature(LOOPBACK_LAYOUT))

    def elaborate(self, platform):
        m = Module()
        # The register may load whenever it is empty or being emptied: full throughput, no skid.
        m.d.comb += self.words_in.ready.eq(~self.words_out.valid | self.words_out.ready)
        with m.If(self.words_in.ready):
            m.d.sync += [
                self.words_out.valid.eq(self.words_in.valid),
                self.words_out.payload.eq(self.words_in.payload),
            ]
        return m


def random_words(rng: random.Random, count: int) -> list[dict]:
    """``count`` payloads spanning every field's range, extremes included."""
    return [
        {
            "depth": rng.choice([-(2**15), 2**15 - 1, rng.randrange(-(2**15), 2**15)]),
            "valid": rng.randrange(2),
            "values": [rng.choice([0, 2**30 - 1, rng.randrange(2**30)]) for _ in range(3)],
            "last": int(k == count - 1),
        }
        for k in range(count)
    ]


class _Bench:
    def __init__(self, dut: HierarchyObject) -> None:
        self.dut = dut
        self.clocking = Clocking(dut.clk)
        self.source = StreamSource(dut, "words_in", LOOPBACK_LAYOUT, self.clocking)
        self.rng = random.Random(cocotb.RANDOM_SEED)

    async def reset(self) -> None:
        self.dut.rst.value = 1
        await ClockCycles(self.dut.clk, 2)
        self.dut.rst.value = 0


@cocotb.test()
async def every_word_in_order_under_idle_and_backpressure(dut: HierarchyObject) -> None:
    bench = _Bench(dut)
    await bench.reset()
    sink = StreamSink(dut, "words_out", LOOPBACK_LAYOUT, bench.clocking, ready=pattern([1, 0, 0, 1, 1, 0]))
    words = random_words(bench.rng, 300)
    await bench.source.send(words, valid=pattern([1, 1, 0, 1, 0]))
    received = await sink.wait_for(len(words))
    assert [t.payload for t in received] == words


@cocotb.test()
async def each_word_leaves_one_clock_after_it_entered(dut: HierarchyObject) -> None:
    bench = _Bench(dut)
    await bench.reset()
    sink = StreamSink(dut, "words_out", LOOPBACK_LAYOUT, bench.clocking)
    words = random_words(bench.rng, 50)
    entered = await bench.source.send(words, valid=pattern([1, 1, 1, 0, 0]))
    received = await sink.wait_for(len(words))
    assert [t.payload for t in received] == words
    start = entered[0]
    assert [bench.clocking.cycle(t.time, since=start) for t in received] == [
        bench.clocking.cycle(t, since=start) + 1 for t in entered
    ]
    # A sink that waits 37 clocks of idle before its next beat must still count cycles exactly.
    await ClockCycles(dut.clk, 37)
    late = await bench.source.send(words[:1])
    received = await sink.wait_for(len(words) + 1)
    assert bench.clocking.cycle(received[-1].time, since=late[0]) == 1


@cocotb.test()
async def a_reset_mid_stream_leaves_the_register_empty(dut: HierarchyObject) -> None:
    bench = _Bench(dut)
    await bench.reset()
    sink = StreamSink(dut, "words_out", LOOPBACK_LAYOUT, bench.clocking, ready=pattern([1, 0]))
    first = random_words(bench.rng, 40)
    sending = cocotb.start_soon(bench.source.send(first))
    await sink.wait_for(10)
    sink.set_ready(pattern([0, 0, 1]))
    await RisingEdge(dut.clk)
    sending.cancel()
    dut.words_in__valid.value = 0
    await bench.reset()
    kept = len(sink.transfers)
    assert [t.payload for t in sink.transfers] == first[:kept]
    await ClockCycles(dut.clk, 3)
    assert len(sink.transfers) == kept, "the register still held a beat after the reset"
    second = random_words(bench.rng, 40)
    await bench.source.send(second)
    received = await sink.wait_for(kept + len(second))
    assert [t.payload for t in received[kept:]] == second
