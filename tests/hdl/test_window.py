# amaranth: UnusedElaboratable=no
"""WindowCorrelator against lost.model: every value, the best fit, every beat's cycle; stalls; reset."""

import itertools
import random

import numpy as np
import pytest

from lost.hdl.interface import best_fit_payload
from lost.hdl.window import WindowCorrelator
from lost.model import best_fit, correlate
from lost.model.cycles import surface_beats
from lost.model.cycles_window import schedule
from lost.sim.amaranth import CorrelatorBench, drain, feed, stream_get

DEPTH_MIN, DEPTH_MAX = -(2**15), 2**15 - 1






def random_case(rng, map_shape, patch_shape, *, extreme=False):
    """A terrain, a patch and a mask with at least one valid node."""
    if extreme:
        terrain = rng.choice([DEPTH_MIN, DEPTH_MAX], size=map_shape).astype(np.int16)
        patch = rng.choice([DEPTH_MIN, DEPTH_MAX], size=patch_shape).astype(np.int16)
        mask = np.ones(patch_shape, dtype=bool)
    else:
        terrain = rng.integers(DEPTH_MIN, DEPTH_MAX + 1, size=map_shape).astype(np.int16)
        patch = rng.integers(DEPTH_MIN, DEPTH_MAX + 1, size=patch_shape).astype(np.int16)
        mask = rng.random(patch_shape) < 0.7
        mask.flat[rng.integers(mask.size)] = True
    return terrain, patch, mask


def random_pattern(seed, busy):
    """Per-cycle flags, high with probability ``1 - busy``."""
    generator = random.Random(seed)
    return (generator.random() >= busy for _ in itertools.count())


def window_bench(**parameters):
    return CorrelatorBench(WindowCorrelator(**parameters))


# (map_shape, patch_shape, lanes): W a multiple of L and not, a row's last beat completed by the next
# row (5x4/1x2/2, 6x12/3x3/4, 5x6/2x2/2), one-group rows (L >= W), 1x1 and one-row/one-column patches
# and maps, a patch as large as the map.
SHAPES = [
    ((6, 7), (2, 3), 1),
    ((5, 4), (1, 2), 2),
    ((7, 8), (3, 2), 2),
    ((8, 9), (3, 4), 3),
    ((6, 10), (5, 4), 4),
    ((3, 9), (2, 5), 4),
    ((5, 5), (1, 1), 1),
    ((4, 3), (2, 1), 4),
    ((1, 6), (1, 3), 3),
    ((9, 1), (4, 1), 1),
    ((12, 13), (4, 4), 1),
    ((6, 12), (3, 3), 4),
    ((5, 6), (2, 2), 2),
    ((1, 1), (1, 1), 4),
    ((2, 2), (2, 2), 3),
]


@pytest.mark.parametrize("map_shape, patch_shape, lanes", SHAPES)
def test_every_value_best_fit_and_cycle(map_shape, patch_shape, lanes):
    rng = np.random.default_rng([*map_shape, *patch_shape, lanes])
    bench = window_bench(map_shape=map_shape, patch_shape=patch_shape, lanes=lanes)
    cases = [random_case(rng, map_shape, patch_shape) for _ in range(2)]
    results = []

    async def testbench(ctx):
        for _run, ((terrain, patch, mask), mode) in enumerate(zip(cases, [True, False])):
            await bench.load(ctx, terrain=terrain, patch=patch, mask=mask)
            results.append(await bench.correlate(ctx, mean_compensation=mode))
        await ctx.tick().repeat(2)  # so that busy is sampled after the last best beat

    bench.run(testbench)
    expected_cycles = schedule(map_shape, patch_shape, lanes)
    for run, ((terrain, patch, mask), mode) in enumerate(zip(cases, [True, False])):
        surface, best = results[run]
        expected = correlate(terrain, patch, mask=mask, mean_compensation=mode)
        np.testing.assert_array_equal(surface, expected)
        assert best == best_fit_payload(best_fit(expected, exclusion_radius=1))
        surface_cycles, best_cycle = bench.cycles(run)
        np.testing.assert_array_equal(surface_cycles, expected_cycles.surface)
        assert best_cycle == expected_cycles.best
        # Busy from the edge after the start beat up to the best beat's edge, idle right after it.
        start = bench.logs["start"][run][0]
        assert all(bench.busy[start + 1:start + best_cycle + 1])
        assert not bench.busy[start + best_cycle + 1]


def test_the_papers_patch_size():
    """A 10 x 10 patch (Nygren's) on a 24 x 37 map with 4 lanes and radius 3: values, best fit, cycles."""
    map_shape, patch_shape, lanes, radius = (24, 37), (10, 10), 4, 3
    bench = window_bench(map_shape=map_shape, patch_shape=patch_shape, lanes=lanes, exclusion_radius=radius)
    terrain, patch, mask = random_case(np.random.default_rng(9), map_shape, patch_shape)
    results = []

    async def testbench(ctx):
        await bench.load(ctx, terrain=terrain, patch=patch, mask=mask)
        results.append(await bench.correlate(ctx, mean_compensation=True))

    bench.run(testbench)
    expected = correlate(terrain, patch, mask=mask)
    np.testing.assert_array_equal(results[0][0], expected)
    assert results[0][1] == best_fit_payload(best_fit(expected, exclusion_radius=radius))
    surface_cycles, best_cycle = bench.cycles(0)
    expected_cycles = schedule(map_shape, patch_shape, lanes, exclusion_radius=radius)
    np.testing.assert_array_equal(surface_cycles, expected_cycles.surface)
    assert best_cycle == expected_cycles.best


# Five and six lanes (the builds after the 4-lane one): W a multiple of L and not, a row's last beat completed
# by the next row, one-group rows (L >= W), and Nygren's 10 x 10 patch.
MORE_LANES = [
    ((7, 13), (3, 4), 5),
    ((6, 15), (2, 3), 5),
    ((5, 4), (2, 2), 5),
    ((8, 14), (3, 3), 6),
    ((16, 29), (10, 10), 5),
]


@pytest.mark.parametrize("map_shape, patch_shape, lanes", MORE_LANES)
def test_five_and_six_lanes(map_shape, patch_shape, lanes):
    """Every value, the best fit and every beat's cycle at 5 and 6 lanes, in both modes."""
    rng = np.random.default_rng([*map_shape, *patch_shape, lanes])
    bench = window_bench(map_shape=map_shape, patch_shape=patch_shape, lanes=lanes, exclusion_radius=2)
    cases = [random_case(rng, map_shape, patch_shape) for _ in range(2)]
    results = []

    async def testbench(ctx):
        for (terrain, patch, mask), mode in zip(cases, [True, False]):
            await bench.load(ctx, terrain=terrain, patch=patch, mask=mask)
            results.append(await bench.correlate(ctx, mean_compensation=mode))

    bench.run(testbench)
    expected_cycles = schedule(map_shape, patch_shape, lanes, exclusion_radius=2)
    for run, ((terrain, patch, mask), mode) in enumerate(zip(cases, [True, False])):
        surface, best = results[run]
        expected = correlate(terrain, patch, mask=mask, mean_compensation=mode)
        np.testing.assert_array_equal(surface, expected)
        assert best == best_fit_payload(best_fit(expected, exclusion_radius=2))
        surface_cycles, best_cycle = bench.cycles(run)
        np.testing.assert_array_equal(surface_cycles, expected_cycles.surface)
        assert best_cycle == expected_cycles.best


@pytest.mark.parametrize("seed", range(8))
def test_random_configurations(seed):
    """Seeded random shapes, lanes, radius, mask and mode: values, best fit and cycles."""
    rng = np.random.default_rng(1000 + seed)
    map_shape = (int(rng.integers(1, 11)), int(rng.integers(1, 15)))
    patch_shape = (int(rng.integers(1, min(map_shape[0], 5) + 1)), int(rng.integers(1, min(map_shape[1], 4) + 1)))
    lanes, radius, mode = int(rng.integers(1, 5)), int(rng.integers(0, 3)), bool(rng.integers(2))
    bench = window_bench(map_shape=map_shape, patch_shape=patch_shape, lanes=lanes, exclusion_radius=radius)
    terrain, patch, mask = random_case(rng, map_shape, patch_shape)
    results = []

    async def testbench(ctx):
        await bench.load(ctx, terrain=terrain, patch=patch, mask=mask)
        results.append(await bench.correlate(ctx, mean_compensation=mode))

    bench.run(testbench)
    surface, best = results[0]
    expected = correlate(terrain, patch, mask=mask, mean_compensation=mode)
    np.testing.assert_array_equal(surface, expected)
    assert best == best_fit_payload(best_fit(expected, exclusion_radius=radius))
    surface_cycles, best_cycle = bench.cycles(0)
    expected_cycles = schedule(map_shape, patch_shape, lanes, exclusion_radius=radius)
    np.testing.assert_array_equal(surface_cycles, expected_cycles.surface)
    assert best_cycle == expected_cycles.best


def check_both_modes(bench, terrain, patch, mask):
    """Load once, correlate in both modes; every value and the best fit against the golden model."""
    results = []

    async def testbench(ctx):
        await bench.load(ctx, terrain=terrain, patch=patch, mask=mask)
        for mode in (True, False):
            results.append(await bench.correlate(ctx, mean_compensation=mode))

    bench.run(testbench)
    for (surface, best), mode in zip(results, (True, False)):
        expected = correlate(terrain, patch, mask=mask, mean_compensation=mode)
        np.testing.assert_array_equal(surface, expected)
        assert best == best_fit_payload(best_fit(expected, exclusion_radius=1))


@pytest.mark.parametrize("lanes", [1, 3])
def test_extreme_depths_reach_the_widths(lanes):
    """All-extreme maps and patches, full mask: the largest terms and sums the widths allow."""
    rng = np.random.default_rng(lanes)
    map_shape, patch_shape = (6, 8), (3, 3)
    bench = window_bench(map_shape=map_shape, patch_shape=patch_shape, lanes=lanes)
    terrain, patch, mask = random_case(rng, map_shape, patch_shape, extreme=True)
    check_both_modes(bench, terrain, patch, mask)


def test_extreme_depths_with_window_sum_copies():
    """A 4 x 6 patch (24 nodes, so three copies of the window sum, each offset), extreme depths."""
    rng = np.random.default_rng(24)
    map_shape, patch_shape = (7, 9), (4, 6)
    bench = window_bench(map_shape=map_shape, patch_shape=patch_shape, lanes=2)
    terrain, patch, mask = random_case(rng, map_shape, patch_shape, extreme=True)
    check_both_modes(bench, terrain, patch, mask)


def test_narrow_depth_words():
    """5-bit depth words at their extremes: every width follows depth_bits."""
    rng = np.random.default_rng(5)
    map_shape, patch_shape, lanes = (7, 9), (3, 4), 2
    bench = window_bench(map_shape=map_shape, patch_shape=patch_shape, lanes=lanes, depth_bits=5)
    terrain = rng.choice([-16, 15, 0], size=map_shape).astype(np.int16)
    patch = rng.choice([-16, 15], size=patch_shape).astype(np.int16)
    mask = rng.random(patch_shape) < 0.8
    mask[0, 0] = True
    check_both_modes(bench, terrain, patch, mask)


@pytest.mark.parametrize("map_shape, patch_shape, lanes, radius", [
    ((7, 9), (2, 3), 2, 0),
    ((8, 7), (3, 2), 3, 2),
    ((5, 6), (2, 2), 1, 1),
])
def test_stalls_on_every_stream(map_shape, patch_shape, lanes, radius):
    """Random gaps on the inputs and random back-pressure on both outputs lose or repeat nothing."""
    rng = np.random.default_rng([*map_shape, *patch_shape, lanes, radius])
    bench = window_bench(map_shape=map_shape, patch_shape=patch_shape, lanes=lanes, exclusion_radius=radius)
    cases = [random_case(rng, map_shape, patch_shape) for _ in range(2)]
    results = []

    async def testbench(ctx):
        for run, (terrain, patch, mask) in enumerate(cases):
            await bench.load(ctx, terrain=terrain, patch=patch, mask=mask, pattern=random_pattern(run, 0.3))
            for mode in (True, False):
                results.append(await bench.correlate(
                    ctx, mean_compensation=mode,
                    surface_pattern=random_pattern(10 + run, 0.5), best_pattern=random_pattern(20 + run, 0.7)))

    bench.run(testbench)
    for k, (surface, best) in enumerate(results):
        terrain, patch, mask = cases[k // 2]
        expected = correlate(terrain, patch, mask=mask, mean_compensation=(k % 2 == 0))
        np.testing.assert_array_equal(surface, expected)
        assert best == best_fit_payload(best_fit(expected, exclusion_radius=radius))


def test_reset_mid_correlation_keeps_the_memories():
    """A reset during a correlation leaves the core idle; the next one, without reloading, is exact."""
    rng = np.random.default_rng(7)
    map_shape, patch_shape, lanes = (7, 9), (3, 4), 2
    bench = window_bench(map_shape=map_shape, patch_shape=patch_shape, lanes=lanes)
    terrain, patch, mask = random_case(rng, map_shape, patch_shape)
    results = []
    idle_after_reset = []

    async def testbench(ctx):
        await bench.load(ctx, terrain=terrain, patch=patch, mask=mask)
        for beats_before_reset in (0, 3):
            await feed(ctx, bench.dut.start, [{"mean_compensation": 1}])
            if beats_before_reset:
                await drain(ctx, bench.dut.surface, beats_before_reset)
            else:
                await ctx.tick().repeat(5)  # still turning the patch ring
            assert ctx.get(bench.dut.busy)
            ctx.set(bench.domain.rst, 1)
            await ctx.tick()
            ctx.set(bench.domain.rst, 0)
            idle_after_reset.append(not ctx.get(bench.dut.busy) and ctx.get(bench.dut.start.ready))
        results.append(await bench.correlate(ctx, mean_compensation=False))
        results.append(await bench.correlate(ctx, mean_compensation=True))

    bench.run(testbench)
    assert idle_after_reset == [True, True]
    for (surface, best), mode in zip(results, (False, True)):
        expected = correlate(terrain, patch, mask=mask, mean_compensation=mode)
        np.testing.assert_array_equal(surface, expected)
        assert best == best_fit_payload(best_fit(expected, exclusion_radius=1))


def test_new_patch_same_map_and_busy_refuses_loads():
    """The map persists across correlations; while busy, neither map nor patch words are taken."""
    rng = np.random.default_rng(11)
    map_shape, patch_shape, lanes = (6, 7), (2, 3), 3
    bench = window_bench(map_shape=map_shape, patch_shape=patch_shape, lanes=lanes)
    terrain, patch, mask = random_case(rng, map_shape, patch_shape)
    _, patch2, mask2 = random_case(rng, map_shape, patch_shape)
    results = []
    refused = []

    async def testbench(ctx):
        await bench.load(ctx, terrain=terrain, patch=patch, mask=mask)
        results.append(await bench.correlate(ctx, mean_compensation=True))
        await bench.load(ctx, patch=patch2, mask=mask2)
        await feed(ctx, bench.dut.start, [{"mean_compensation": 1}])
        refused.append(not ctx.get(bench.dut.map_in.ready) and not ctx.get(bench.dut.patch_in.ready)
                       and not ctx.get(bench.dut.start.ready))
        beats = len(surface_beats(bench.parameters.surface_shape, lanes))
        await drain(ctx, bench.dut.surface, beats)
        await stream_get(ctx, bench.dut.best)

    bench.run(testbench)
    surface, best = results[0]
    expected = correlate(terrain, patch, mask=mask)
    np.testing.assert_array_equal(surface, expected)
    assert refused == [True]
    second = [payload for _, payload in bench.logs["surface"][-len(surface_beats(bench.parameters.surface_shape, lanes)):]]
    rebuilt = np.zeros(bench.parameters.surface_shape, dtype=np.int64)
    for beat in second:
        rebuilt[beat["i"], beat["j"]:beat["j"] + beat["count"]] = beat["values"][:beat["count"]]
    np.testing.assert_array_equal(rebuilt, correlate(terrain, patch2, mask=mask2))


@pytest.mark.parametrize("kwargs, message", [
    ({"map_shape": (4, 4), "patch_shape": (5, 2), "lanes": 1}, "larger than the map"),
    ({"map_shape": (4, 4), "patch_shape": (2, 2), "lanes": 0}, "lanes"),
    ({"map_shape": (4, 4), "patch_shape": (2, 2), "lanes": 2, "exclusion_radius": -1}, "exclusion_radius"),
])
def test_bad_parameters_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        WindowCorrelator(**kwargs)
