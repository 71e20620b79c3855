# amaranth: UnusedElaboratable=no
"""The recursive core's components alone against NumPy models: NodeCompaction's node list, TermUnit's sums."""

import numpy as np
import pytest
from amaranth.sim import Simulator

from lost.hdl.interface import CorrelatorParameters
from lost.hdl.recursive_patch import NodeCompaction
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


@pytest.mark.parametrize("map_shape, patch_shape, mode, share", [((7, 9), (3, 4), True, 0.6), ((5, 5), (2, 2), False, 0.7),
                                                                  ((4, 6), (2, 3), True, 0.0), ((3, 3), (1, 1), True, 1.0)])
def test_node_compaction_lists_the_valid_nodes_with_their_centred_depths(map_shape, patch_shape, mode, share):
    (_, W), (h, w) = map_shape, patch_shape
    rng = np.random.default_rng([h, w, int(mode)])
    params = CorrelatorParameters(map_shape=map_shape, patch_shape=patch_shape, depth_bits=16, lanes=1)
    dut = NodeCompaction(parameters=params)
    patch = rng.integers(-(2**15), 2**15, size=patch_shape)
    mask = rng.random(patch_shape) < share
    n = int(mask.sum())
    f = n if mode else 1
    patch_sum = int(patch[mask].sum())
    expected = [(k * W + l, f * int(patch[k, l]) - (patch_sum if mode else 0))
                for k in range(h) for l in range(w) if mask[k, l]]
    written, result = [], {}

    async def bench(ctx):
        ctx.set(dut.accept, 1)
        for depth, valid in zip(patch.flat, mask.flat):
            ctx.set(dut.patch_in.valid, 1)
            ctx.set(dut.patch_in.payload, {"depth": int(depth), "valid": bool(valid)})
            await ctx.tick()
        ctx.set(dut.patch_in.valid, 0)
        ctx.set(dut.accept, 0)
        ctx.set(dut.start, 1)
        ctx.set(dut.start_mode, mode)
        await ctx.tick()  # edge 0: the start beat
        ctx.set(dut.start, 0)
        for edge in range(1, 2 * h * w + 6):
            done = ctx.get(dut.done)
            if ctx.get(dut.nodes_write.en):
                written.append((ctx.get(dut.nodes_write.addr), ctx.get(dut.nodes_write.data.offset),
                                ctx.get(dut.nodes_write.data.centred)))
            await ctx.tick()
            if done:
                result.update(done_edge=edge, empty=ctx.get(dut.empty), count_last=ctx.get(dut.count_last),
                              factor=ctx.get(dut.factor), mean=ctx.get(dut.mean))

    sim = Simulator(dut)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    assert written == [(index, offset, centred) for index, (offset, centred) in enumerate(expected)]
    assert result["done_edge"] == 2 * h * w + 3
    assert (result["empty"], result["factor"], result["mean"]) == (n == 0, f, int(mode))
    if n:
        assert result["count_last"] == n - 1
