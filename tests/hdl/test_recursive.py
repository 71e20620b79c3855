# amaranth: UnusedElaboratable=no
"""RecursiveCorrelator against lost.model: every value, the best fit, every beat's cycle; stalls; reset."""

import itertools

import numpy as np
import pytest

from lost.hdl.interface import best_fit_payload
from lost.hdl.recursive import RecursiveCorrelator
from lost.model import best_fit, correlate
from lost.model.cycles_recursive import schedule
from lost.sim.amaranth import CorrelatorBench, drain, feed, stream_get, stream_put


def patch_words(patch, mask):
    return [{"depth": int(d), "valid": int(v)} for d, v in zip(patch.ravel(), mask.ravel())]


def recursive_bench(**parameters):
    return CorrelatorBench(RecursiveCorrelator(**parameters))


def random_case(rng, map_shape, patch_shape, *, sparse):
    terrain = rng.integers(-(2**15), 2**15, map_shape).astype(np.int16)
    patch = rng.integers(-(2**15), 2**15, patch_shape).astype(np.int16)
    # Rough terrain and a patch cut from it (plus noise): realistic surfaces with a clear best fit.
    if rng.random() < 0.5:
        terrain = (rng.integers(-300, 300, map_shape)).astype(np.int16)
        i, j = rng.integers(0, map_shape[0] - patch_shape[0] + 1), rng.integers(0, map_shape[1] - patch_shape[1] + 1)
        patch = (terrain[i:i + patch_shape[0], j:j + patch_shape[1]] + rng.integers(-3, 4, patch_shape)).astype(np.int16)
    mask = rng.random(patch_shape) < (0.5 if sparse else 1.0)
    if not mask.any():
        mask[0, 0] = True
    return terrain, patch, mask


@pytest.mark.parametrize(("map_shape", "patch_shape", "radius"),
                         [((6, 7), (2, 3), 1), ((5, 5), (3, 2), 0), ((4, 9), (4, 3), 2), ((3, 3), (1, 1), 1)])
def test_random_cases_every_value_and_cycle(map_shape, patch_shape, radius):
    rng = np.random.default_rng(sum(map_shape) * 10 + sum(patch_shape))
    cases = [random_case(rng, map_shape, patch_shape, sparse=k % 2 == 1) + (k % 3 != 2,) for k in range(4)]
    bench = recursive_bench(map_shape=map_shape, patch_shape=patch_shape, exclusion_radius=radius)
    results = []

    async def testbench(ctx):
        for terrain, patch, mask, mean in cases:
            await feed(ctx, bench.dut.map_in, [int(x) for x in terrain.ravel()])
            await feed(ctx, bench.dut.patch_in, patch_words(patch, mask))
            results.append(await bench.correlate(ctx, mean_compensation=mean))

    bench.sim.add_testbench(testbench)
    bench.sim.run()
    for run, ((terrain, patch, mask, mean), (surface, best)) in enumerate(zip(cases, results)):
        golden = correlate(terrain, patch, mask=mask, mean_compensation=mean)
        np.testing.assert_array_equal(surface, golden)
        assert best == best_fit_payload(best_fit(golden, exclusion_radius=radius))
        model = schedule(map_shape, patch_shape, mask, mean, exclusion_radius=radius)
        surface_cycles, best_cycle = bench.cycles(run)
        assert surface_cycles == model.surface.tolist()
        assert best_cycle == model.best


def test_extreme_depths_reach_the_widths():
    # Alternating extremes: the largest differences and sums the widths must hold.
    map_shape, patch_shape = (4, 5), (3, 3)
    terrain = np.where(np.indices(map_shape).sum(axis=0) % 2, 2**15 - 1, -(2**15)).astype(np.int16)
    patch = np.where(np.indices(patch_shape).sum(axis=0) % 2, -(2**15), 2**15 - 1).astype(np.int16)
    mask = np.ones(patch_shape, dtype=bool)
    bench = recursive_bench(map_shape=map_shape, patch_shape=patch_shape)
    results = []

    async def testbench(ctx):
        await feed(ctx, bench.dut.map_in, [int(x) for x in terrain.ravel()])
        await feed(ctx, bench.dut.patch_in, patch_words(patch, mask))
        for mean in (True, False):
            results.append(await bench.correlate(ctx, mean_compensation=mean))

    bench.sim.add_testbench(testbench)
    bench.sim.run()
    for (surface, best), mean in zip(results, (True, False)):
        golden = correlate(terrain, patch, mask=mask, mean_compensation=mean)
        np.testing.assert_array_equal(surface, golden)
        assert best == best_fit_payload(best_fit(golden, exclusion_radius=1))
    assert results[1][0].max() == 9 * (2**16 - 1)


@pytest.mark.parametrize("pattern", [[1, 0], [0, 0, 1], [1, 1, 1, 0, 0]])
def test_output_stalls_lose_nothing(pattern):
    rng = np.random.default_rng(len(pattern))
    map_shape, patch_shape = (5, 6), (2, 3)
    terrain, patch, mask = random_case(rng, map_shape, patch_shape, sparse=True)
    bench = recursive_bench(map_shape=map_shape, patch_shape=patch_shape)
    results = []

    async def testbench(ctx):
        await feed(ctx, bench.dut.map_in, [int(x) for x in terrain.ravel()],
                   pattern=itertools.cycle([1, 0, 1]))
        await feed(ctx, bench.dut.patch_in, patch_words(patch, mask), pattern=itertools.cycle([0, 1]))
        for mean in (True, False):
            results.append(await bench.correlate(ctx, mean_compensation=mean,
                                                 surface_pattern=itertools.cycle(pattern), best_pattern=itertools.chain([0] * 7, itertools.repeat(1))))

    bench.sim.add_testbench(testbench)
    bench.sim.run()
    for (surface, best), mean in zip(results, (True, False)):
        golden = correlate(terrain, patch, mask=mask, mean_compensation=mean)
        np.testing.assert_array_equal(surface, golden)
        assert best == best_fit_payload(best_fit(golden, exclusion_radius=1))


def test_random_stalls_lose_nothing():
    rng = np.random.default_rng(5)
    map_shape, patch_shape = (6, 6), (3, 3)
    terrain, patch, mask = random_case(rng, map_shape, patch_shape, sparse=False)
    bench = recursive_bench(map_shape=map_shape, patch_shape=patch_shape)
    results = []

    async def testbench(ctx):
        await feed(ctx, bench.dut.map_in, [int(x) for x in terrain.ravel()])
        await feed(ctx, bench.dut.patch_in, patch_words(patch, mask))
        results.append(await bench.correlate(ctx, mean_compensation=True,
                                             surface_pattern=(bool(x) for x in rng.random(100_000) < 0.3)))

    bench.sim.add_testbench(testbench)
    bench.sim.run()
    golden = correlate(terrain, patch, mask=mask)
    np.testing.assert_array_equal(results[0][0], golden)
    assert results[0][1] == best_fit_payload(best_fit(golden, exclusion_radius=1))


def test_reset_mid_correlation_then_a_correct_one():
    rng = np.random.default_rng(9)
    map_shape, patch_shape = (6, 7), (3, 2)
    terrain, patch, mask = random_case(rng, map_shape, patch_shape, sparse=True)
    other_patch = rng.integers(-500, 500, patch_shape).astype(np.int16)
    bench = recursive_bench(map_shape=map_shape, patch_shape=patch_shape)
    results, busy_before_reset, busy_after_reset = [], [], []

    async def reset(ctx):
        busy_before_reset.append(ctx.get(bench.dut.busy))
        ctx.set(bench.domain.rst, 1)
        await ctx.tick()
        ctx.set(bench.domain.rst, 0)
        busy_after_reset.append(ctx.get(bench.dut.busy))

    async def testbench(ctx):
        await feed(ctx, bench.dut.map_in, [int(x) for x in terrain.ravel()])
        await feed(ctx, bench.dut.patch_in, patch_words(patch, mask))
        # Reset while the surface streams, with a beat on offer.
        await stream_put(ctx, bench.dut.start, {"mean_compensation": 1})
        await drain(ctx, bench.dut.surface, 5)
        await ctx.tick().until(bench.dut.surface.valid)
        await reset(ctx)
        # Same map and patch, not reloaded.
        results.append(await bench.correlate(ctx, mean_compensation=False))
        # Reset during preparation, then a new patch.
        await stream_put(ctx, bench.dut.start, {"mean_compensation": 1})
        await ctx.tick().repeat(3)
        await reset(ctx)
        await feed(ctx, bench.dut.patch_in, patch_words(other_patch, mask))
        results.append(await bench.correlate(ctx, mean_compensation=True))
        # Reset while the reducer scans, after the whole surface, before the best beat.
        await stream_put(ctx, bench.dut.start, {"mean_compensation": 0})
        await drain(ctx, bench.dut.surface, 4 * 6)
        await ctx.tick().repeat(4)
        await reset(ctx)
        results.append(await bench.correlate(ctx, mean_compensation=True))

    bench.sim.add_testbench(testbench)
    bench.sim.run()
    assert busy_before_reset == [1, 1, 1]
    assert busy_after_reset == [0, 0, 0]
    assert len(results) == 3
    for (surface, best), (this_patch, mean) in zip(results, [(patch, False), (other_patch, True), (other_patch, True)]):
        golden = correlate(terrain, this_patch, mask=mask, mean_compensation=mean)
        np.testing.assert_array_equal(surface, golden)
        assert best == best_fit_payload(best_fit(golden, exclusion_radius=1))


def test_a_patch_without_valid_nodes_gives_a_zero_surface():
    # The host refuses such a patch; the core must still finish, with nothing accumulated.
    map_shape, patch_shape = (5, 6), (2, 3)
    rng = np.random.default_rng(3)
    terrain = rng.integers(-1000, 1000, map_shape).astype(np.int16)
    bench = recursive_bench(map_shape=map_shape, patch_shape=patch_shape)
    results = []

    async def testbench(ctx):
        await feed(ctx, bench.dut.map_in, [int(x) for x in terrain.ravel()])
        await feed(ctx, bench.dut.patch_in, [{"depth": 77, "valid": 0}] * 6)
        for mean in (True, False):
            results.append(await bench.correlate(ctx, mean_compensation=mean))

    bench.sim.add_testbench(testbench)
    bench.sim.run()
    zeros = np.zeros((4, 4), dtype=np.int64)
    for surface, best in results:
        np.testing.assert_array_equal(surface, zeros)
        assert best == best_fit_payload(best_fit(zeros, exclusion_radius=1))


def test_inputs_are_refused_while_busy():
    map_shape, patch_shape = (4, 4), (2, 2)
    bench = recursive_bench(map_shape=map_shape, patch_shape=patch_shape)
    seen = []

    async def testbench(ctx):
        await feed(ctx, bench.dut.map_in, list(range(16)))
        await feed(ctx, bench.dut.patch_in, [{"depth": 1, "valid": 1}] * 4)
        await stream_put(ctx, bench.dut.start, {"mean_compensation": 1})
        seen.append((ctx.get(bench.dut.busy), ctx.get(bench.dut.map_in.ready),
                     ctx.get(bench.dut.patch_in.ready), ctx.get(bench.dut.start.ready)))
        await drain(ctx, bench.dut.surface, 9)
        await stream_get(ctx, bench.dut.best)
        await ctx.tick()
        seen.append((ctx.get(bench.dut.busy), ctx.get(bench.dut.map_in.ready),
                     ctx.get(bench.dut.patch_in.ready), ctx.get(bench.dut.start.ready)))

    bench.sim.add_testbench(testbench)
    bench.sim.run()
    assert seen == [(1, 0, 0, 0), (0, 1, 1, 1)]


def test_start_refused_on_every_cycle_until_the_best_beat():
    map_shape, patch_shape = (5, 5), (2, 2)
    bench = recursive_bench(map_shape=map_shape, patch_shape=patch_shape)
    readiness = []

    async def testbench(ctx):
        await feed(ctx, bench.dut.map_in, list(range(25)))
        await feed(ctx, bench.dut.patch_in, [{"depth": d, "valid": 1} for d in (3, 1, 4, 1)])
        await stream_put(ctx, bench.dut.start, {"mean_compensation": 1})
        ctx.set(bench.dut.surface.ready, 1)
        ctx.set(bench.dut.best.ready, 1)
        while True:
            _, _, start_ready, map_ready, patch_ready, best_done = await ctx.tick().sample(
                bench.dut.start.ready, bench.dut.map_in.ready, bench.dut.patch_in.ready,
                bench.dut.best.valid & bench.dut.best.ready)
            readiness.append((start_ready, map_ready, patch_ready))
            if best_done:
                break
        await ctx.tick()
        readiness.append((ctx.get(bench.dut.start.ready), ctx.get(bench.dut.map_in.ready),
                          ctx.get(bench.dut.patch_in.ready)))

    bench.sim.add_testbench(testbench)
    bench.sim.run()
    assert len(readiness) == schedule(map_shape, patch_shape).best + 1
    assert set(readiness[:-1]) == {(0, 0, 0)} and readiness[-1] == (1, 1, 1)


def test_rejects_bad_parameters():
    with pytest.raises(ValueError, match="larger than the map"):
        RecursiveCorrelator(map_shape=(4, 4), patch_shape=(5, 1))
    with pytest.raises(ValueError, match="exclusion_radius"):
        RecursiveCorrelator(map_shape=(4, 4), patch_shape=(2, 2), exclusion_radius=-1)
