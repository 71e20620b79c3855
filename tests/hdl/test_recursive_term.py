# amaranth: UnusedElaboratable=no
"""The recursive core's TermUnit alone: sum |f * M - offset| per placement, at its latency, under back-pressure."""

import numpy as np
import pytest
from amaranth.sim import Simulator

from lost.hdl.interface import CorrelatorParameters
from lost.hdl.recursive_term import TermStage, TermUnit

PARAMS = CorrelatorParameters(map_shape=(6, 6), patch_shape=(3, 3), depth_bits=16, lanes=1)


def placements(rng, count, factor):
    """Terms of ``count`` placements: (word, offset) pairs, 1 to 9 a placement, offsets as a core forms them."""
    out = []
    for _ in range(count):
        terms = rng.integers(1, 10)
        words = rng.integers(-(2**15), 2**15, terms)
        offsets = rng.integers(-(2**15), 2**15, terms) * factor  # within C + Msum's range for n <= 9
        out.append(list(zip(words.tolist(), offsets.tolist())))
    return out


@pytest.mark.parametrize("factor, empty, ready_share, gap_share", [(9, False, 1.0, 0.0), (7, False, 0.4, 0.3),
                                                                   (1, False, 0.7, 0.0), (5, True, 0.5, 0.2)])
def test_every_placements_value_in_order(factor, empty, ready_share, gap_share):
    rng = np.random.default_rng([factor, int(empty), int(10 * ready_share)])
    dut = TermUnit(parameters=PARAMS)
    work = placements(rng, 40, factor)
    expected = [0 if empty else sum(abs(factor * word - offset) for word, offset in terms) for terms in work]
    stream = [(word, offset, k == 0, k == len(terms) - 1) for terms in work for k, (word, offset) in enumerate(terms)]
    received, first_valid = [], []

    async def bench(ctx):
        ctx.set(dut.factor, factor)
        ctx.set(dut.empty, empty)
        index, edge = 0, 0
        while len(received) < len(work):
            offer = index < len(stream) and rng.random() >= gap_share
            word, offset, first, last = stream[index] if offer else (0, 0, False, False)
            ctx.set(dut.term, {"valid": offer, "first": first, "last": last, "offset": offset})
            ready = bool(rng.random() < ready_share)
            ctx.set(dut.value.ready, ready)
            taken = offer and ctx.get(dut.advance)
            if ctx.get(dut.value.valid) and ready:
                received.append(ctx.get(dut.value.payload))
            await ctx.tick()
            edge += 1
            if taken:
                ctx.set(dut.word, word)  # the memory read on the taking edge, held until the next
                index += 1
                if last and ready_share == 1.0:
                    first_valid.append(edge)
            if ready_share == 1.0 and ctx.get(dut.value.valid) and len(first_valid) > len(received):
                # Ready always high: valid rises exactly ACCUMULATE + 1 edges after the last term's edge.
                assert edge == first_valid[len(received)] + TermStage.ACCUMULATE, (edge, first_valid)
            assert edge < 20 * len(stream), "the unit stopped taking terms"

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    assert received == expected
