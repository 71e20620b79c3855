# amaranth: UnusedElaboratable=no
"""BitCount: the set bits among its leaves, with an AdderTree's latency, against NumPy on random bits."""

import numpy as np
import pytest
from amaranth.hdl import Cat, ClockDomain, Const, Module, Signal
from amaranth.sim import Simulator

from lost.hdl.blocks import AdderTree, BitCount, _count_bits, tree_levels


@pytest.mark.parametrize("count", [1, 2, 3, 4, 5, 7, 8, 9, 12, 13, 17, 100])
@pytest.mark.parametrize("adders_per_register", [1, 2, 3])
def test_bit_count_counts_with_the_adder_trees_latency(count, adders_per_register):
    dut = BitCount(count=count, total=count, adders_per_register=adders_per_register)
    reference = AdderTree(count=count, leaf=(0, 1), total=(0, count), adders_per_register=adders_per_register)
    assert dut.latency == reference.latency == tree_levels(count)
    assert len(dut.sum) == len(reference.sum)
    rng = np.random.default_rng([count, adders_per_register])
    # All ones and all zeros first, then random bits of varied density.
    words = [(1 << count) - 1, 0] + [int(sum(1 << k for k in range(count) if rng.random() < p))
                                     for p in rng.random(40)]
    seen = []

    async def bench(ctx):
        for word in words + [0] * dut.latency:
            ctx.set(dut.leaves, word)
            seen.append(ctx.get(dut.sum))  # before the edge: the count of the word latency loads ago
            await ctx.tick()

    top = Module()
    top.domains.sync = ClockDomain()
    top.submodules.dut = dut
    sim = Simulator(top)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    expected = [bin(word).count("1") for word in words]
    assert seen[dut.latency:dut.latency + len(words)] == expected


def test_count_bits_is_the_binary_count_of_up_to_four_bits():
    for n in range(1, 5):
        for value in range(1 << n):
            bits = [Const((value >> k) & 1, 1) for k in range(n)]
            result = Cat(*_count_bits(bits))
            # Evaluate the constant expression through a one-signal simulation.
            m = Module()
            out = Signal(len(result))
            m.d.comb += out.eq(result)
            got = []

            async def bench(ctx, out=out, got=got):
                got.append(ctx.get(out))

            sim = Simulator(m)
            sim.add_testbench(bench)
            sim.run()
            assert got == [bin(value).count("1")], (n, value)


@pytest.mark.parametrize("total", [-1, 5, True])
def test_bit_count_refuses_a_total_outside_the_count(total):
    with pytest.raises(ValueError, match="total"):
        BitCount(count=4, total=total)
