# amaranth: UnusedElaboratable=no
"""The window core's acceptance as registers: ``busy`` on every edge, and the lanes' own load enables."""

import itertools
import random

import numpy as np
import pytest
from amaranth.hdl import ClockDomain, Module
from amaranth.sim import Simulator

from lost.hdl.interface import CorrelatorParameters
from lost.hdl.window import WindowCorrelator
from lost.hdl.window_patch import PatchPreparation
from lost.model import correlate
from lost.sim.amaranth import CorrelatorBench

B = 16


def _pattern(seed, busy):
    generator = random.Random(seed)
    return (generator.random() >= busy for _ in itertools.count())


def test_busy_on_every_edge_from_start_to_the_best_beat_with_stalls():
    """``busy`` (now a register formed from next values) is high exactly from the edge after each start
    beat through the edge its best beat transfers, with the surface and best streams stalled at random
    and patches reloaded between correlations."""
    rng = np.random.default_rng(23)
    map_shape, patch_shape, lanes = (6, 9), (3, 4), 3
    bench = CorrelatorBench(WindowCorrelator(map_shape=map_shape, patch_shape=patch_shape, lanes=lanes))
    terrain = rng.integers(-500, 500, size=map_shape).astype(np.int16)
    patches = [(rng.integers(-500, 500, size=patch_shape).astype(np.int16), rng.random(patch_shape) < 0.8)
               for _ in range(3)]
    results = []

    async def testbench(ctx):
        await bench.load(ctx, terrain=terrain)
        for run, (patch, mask) in enumerate(patches):
            mask.flat[0] = True
            await bench.load(ctx, patch=patch, mask=mask, pattern=_pattern(run, 0.4))
            results.append(await bench.correlate(ctx, mean_compensation=bool(run % 2),
                                                 surface_pattern=_pattern(10 + run, 0.5),
                                                 best_pattern=_pattern(20 + run, 0.8)))
            if run:
                await ctx.tick().repeat(run)  # the next patch right after the best beat, then later
        await ctx.tick().repeat(3)

    bench.run(testbench)
    spans = [(start, best) for (start, _), (best, _) in zip(bench.logs["start"], bench.logs["best"])]
    assert len(spans) == 3
    expected = [any(start < edge <= best for start, best in spans) for edge in range(len(bench.busy))]
    assert [bool(b) for b in bench.busy] == expected
    for (surface, _), (patch, mask), run in zip(results, patches, itertools.count()):
        np.testing.assert_array_equal(surface, correlate(terrain, patch, mask=mask, mean_compensation=bool(run % 2)))


@pytest.mark.parametrize("held_lane", [None, 1])
def test_patch_preparation_lane_resets_are_the_invalid_bits_each_on_its_own_enable(held_lane):
    """With ``lane_resets``, each lane's copy holds the invalid bits and loads on its own enable: driven
    equal to ``accept``, every copy equals ``~patch_valid`` on every cycle (loads, a reset, a pass); a lane
    whose enable is held low keeps its copy (so the port, not ``accept``, is that copy's enable)."""
    h, w, lanes = 3, 4, 3
    nodes = h * w
    rng = np.random.default_rng(31)
    params = CorrelatorParameters(map_shape=(4, 5), patch_shape=(h, w), depth_bits=B, lanes=lanes)
    dut = PatchPreparation(parameters=params, lane_resets=True)
    assert "lane_patch_valid" not in dut.signature.members
    top = Module()
    top.domains.sync = sync = ClockDomain()
    top.submodules.dut = dut
    seen, held = [], []

    def check(ctx):
        valid = ctx.get(dut.patch_valid)
        seen.append(valid)
        for q in range(lanes):
            copy = ctx.get(dut.lane_patch_invalid[q])
            if q == held_lane:
                held.append(copy)
            else:
                assert copy == valid ^ ((1 << nodes) - 1)

    async def bench(ctx):
        ctx.set(dut.idle, 1)
        check(ctx)
        for cycle in range(4 * nodes):
            accept = int(rng.random() < 0.8)
            ctx.set(dut.accept, accept)
            for q in range(lanes):
                ctx.set(dut.lane_accept[q], 0 if q == held_lane else accept)
            ctx.set(dut.patch_in.valid, int(rng.random() < 0.7))
            ctx.set(dut.patch_in.payload, {"depth": int(rng.integers(-100, 100)), "valid": bool(rng.random() < 0.5)})
            ctx.set(sync.rst, int(cycle == 2 * nodes))
            await ctx.tick()
            check(ctx)
        ctx.set(dut.patch_in.valid, 0)
        ctx.set(dut.start, 1)
        await ctx.tick()
        ctx.set(dut.start, 0)
        ctx.set(dut.idle, 0)
        for _ in range(nodes + 4):
            await ctx.tick()
            check(ctx)

    sim = Simulator(top)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    assert len(set(seen)) > 5
    if held_lane is not None:
        assert set(held) == {(1 << nodes) - 1}  # reset-less, initially all invalid, never loaded


def test_patch_preparation_refuses_a_non_bool_lane_resets():
    params = CorrelatorParameters(map_shape=(4, 5), patch_shape=(2, 2), depth_bits=B, lanes=2)
    with pytest.raises(ValueError, match="lane_resets must be a bool"):
        PatchPreparation(parameters=params, lane_resets=1)
