# amaranth: UnusedElaboratable=no
"""AddressGenerator alone against a Python model: every map read of every placement and the flush round, in order."""

import numpy as np
import pytest
from amaranth.hdl import Module
from amaranth.lib import memory, wiring
from amaranth.sim import Simulator

from lost.hdl.interface import CorrelatorParameters
from lost.hdl.recursive_address import AddressGenerator


def expected_requests(map_shape, patch_shape, mask, centred):
    """``(addr, index, first, last, centred, current, previous)`` of every request, in order (centred None: any)."""
    (H, W), (h, w) = map_shape, patch_shape
    nodes = [(k * W + l, int(centred[k, l])) for k in range(h) for l in range(w) if mask[k, l]]
    corners = [i * W + j for i in range(H - h + 1) for j in range(W - w + 1)]
    out = []
    # The flush round reads at the last placement's corner, its words belonging to no placement.
    for q, corner in enumerate(corners + corners[-1:]):
        current, previous = q < len(corners), q > 0
        if not nodes:
            out.append((corner, 0, True, True, None, current, previous))
        for k, (offset, c) in enumerate(nodes):
            out.append((corner + offset, k, k == 0, k == len(nodes) - 1, c, current, previous))
    return out


def run_generator(map_shape, patch_shape, mask, centred, *, ready_share, runs, seed):
    """Each run's transfers as ``(edge after its start, addr, index, first, last, centred, current, previous)``."""
    (_, W), (h, w) = map_shape, patch_shape
    rng = np.random.default_rng(seed)
    params = CorrelatorParameters(map_shape=map_shape, patch_shape=patch_shape, depth_bits=16, lanes=1)
    dut = AddressGenerator(parameters=params)
    nodes = [{"offset": k * W + l, "centred": int(centred[k, l])} for k in range(h) for l in range(w) if mask[k, l]]
    # The words past the list are stale in the core; here they are junk that must never be read as a node.
    junk = [{"offset": int(rng.integers(0, (h - 1) * W + w)), "centred": int(rng.integers(-(2**15), 2**15))}
            for _ in range(h * w - len(nodes))]
    m = Module()
    m.submodules.generator = dut
    m.submodules.nodes = nodes_memory = memory.Memory(shape=dut.node_layout, depth=h * w, init=nodes + junk)
    wiring.connect(m, dut.nodes_read, nodes_memory.read_port())
    expected_count = len(expected_requests(map_shape, patch_shape, mask, centred))
    transfers = [[] for _ in range(runs)]

    async def bench(ctx):
        ctx.set(dut.count_last, max(len(nodes) - 1, 0))
        ctx.set(dut.empty, not nodes)
        for run in range(runs):
            for _ in range(int(rng.integers(0, 4))):  # idle between runs
                await ctx.tick()
            ctx.set(dut.start, 1)
            await ctx.tick()  # edge 0
            ctx.set(dut.start, 0)
            edge = 0
            # Past the last expected request, a while longer: no request may follow.
            while len(transfers[run]) < expected_count or edge < expected_count + 30:
                ready = bool(rng.random() < ready_share)
                ctx.set(dut.request.ready, ready)
                if ctx.get(dut.request.valid) and ready:
                    tag = ctx.get(dut.request.payload.tag)
                    transfers[run].append((edge + 1, ctx.get(dut.request.payload.addr), tag.index, bool(tag.first),
                                           bool(tag.last), tag.centred, bool(tag.current), bool(tag.previous)))
                await ctx.tick()
                edge += 1
                assert edge < 20 * expected_count + 100, "the generator stopped requesting"

    sim = Simulator(m)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    return transfers


def check(transfers, expected):
    assert len(transfers) == len(expected)
    for got, want in zip(transfers, expected):
        if want[4] is None:  # no valid node: the tag's centred depth is unused
            got, want = got[:4] + got[5:], want[:4] + want[5:]
        assert got == want


def random_mask(rng, patch_shape, kind):
    if kind == "full":
        return np.ones(patch_shape, dtype=bool)
    if kind == "none":
        return np.zeros(patch_shape, dtype=bool)
    mask = np.zeros(patch_shape, dtype=bool)
    if kind == "one":
        mask[rng.integers(patch_shape[0]), rng.integers(patch_shape[1])] = True
    else:
        mask = rng.random(patch_shape) < 0.4
    return mask


@pytest.mark.parametrize("map_shape, patch_shape, kind, ready_share", [
    ((7, 9), (3, 4), "full", 0.6),
    ((6, 7), (2, 3), "sparse", 0.5),
    ((5, 8), (3, 3), "one", 0.7),
    ((4, 5), (2, 2), "none", 0.5),
    ((3, 3), (1, 1), "full", 0.3),
    ((5, 4), (5, 1), "sparse", 0.8),
])
def test_every_request_in_order_under_random_ready(map_shape, patch_shape, kind, ready_share):
    rng = np.random.default_rng([*map_shape, *patch_shape, len(kind)])
    mask = random_mask(rng, patch_shape, kind)
    centred = rng.integers(-(2**15), 2**15, patch_shape)
    expected = expected_requests(map_shape, patch_shape, mask, centred)
    runs = run_generator(map_shape, patch_shape, mask, centred, ready_share=ready_share, runs=2, seed=rng.integers(1 << 30))
    for transfers in runs:  # a second start after the flush round: the generator returned to its idle state
        check([t[1:] for t in transfers], expected)


@pytest.mark.parametrize("kind", ["full", "sparse", "none"])
def test_one_request_a_clock_from_edge_two_with_ready_high(kind):
    map_shape, patch_shape = (6, 8), (2, 3)
    rng = np.random.default_rng(len(kind))
    mask = random_mask(rng, patch_shape, kind)
    centred = rng.integers(-(2**15), 2**15, patch_shape)
    expected = expected_requests(map_shape, patch_shape, mask, centred)
    (H, W), (h, w) = map_shape, patch_shape
    assert len(expected) == max(int(mask.sum()), 1) * ((H - h + 1) * (W - w + 1) + 1)
    (transfers,) = run_generator(map_shape, patch_shape, mask, centred, ready_share=1.0, runs=1, seed=3)
    check([t[1:] for t in transfers], expected)
    assert [t[0] for t in transfers] == list(range(2, 2 + len(expected)))
