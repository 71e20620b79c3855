# amaranth: UnusedElaboratable=no
"""The window core's components, each alone against a NumPy model at the latency its docstring states."""

import numpy as np
import pytest
from amaranth.hdl import ClockDomain, Module
from amaranth.sim import Simulator

from lost.hdl.interface import CorrelatorParameters
from lost.hdl.window_columns import StepWindow
from lost.hdl.window_lane import WindowLane
from lost.hdl.window_patch import PatchPreparation
from lost.hdl.window_queue import CreditQueue
from lost.model import correlate

from .test_blocks import simulate

B = 16
LIFT = 1 << B


def patch_terms(patch, mask, mode):
    """What the patch preparation hands the lanes: f, the lifted depths, the dividend's bias."""
    n = int(mask.sum())
    f = n if mode else 1
    patch_sum = int(patch[mask].astype(np.int64).sum())
    return f, [LIFT - int(s) for s in patch.flat], (f << B if mode else 0) - patch_sum


# (patch shape, mode, depth range, advance pattern): both modes, extreme depths, steps with gaps.
LANE_CASES = [
    ((3, 4), True, 2**15, None),
    ((3, 4), False, 2**15, None),
    ((2, 5), True, 300, [1, 0, 0, 1, 1, 0, 1]),
    ((1, 1), True, 2**15, [1, 0]),
    ((4, 3), False, 2**15, [1, 1, 0]),
]


@pytest.mark.parametrize("patch_shape, mode, span, pattern", LANE_CASES)
def test_lane_values_are_the_models_at_its_latency(patch_shape, mode, span, pattern):
    h, w = patch_shape
    rng = np.random.default_rng([h, w, int(mode), span])
    params = CorrelatorParameters(map_shape=(h, w), patch_shape=patch_shape, depth_bits=B, lanes=1)
    lane = WindowLane(parameters=params)
    stages = lane.stages
    D, T = stages.window_to_quotient, stages.value
    patch = rng.integers(-span, span, size=patch_shape).astype(np.int16)
    mask = rng.random(patch_shape) < 0.7
    mask.flat[0] = True
    placements = [rng.integers(-span, span, size=patch_shape).astype(np.int16) for _ in range(12)]
    if span == 2**15:  # the extremes of the depth word
        placements[3] = np.full(patch_shape, 2**15 - 1, np.int16)
        placements[4] = np.full(patch_shape, -(2**15), np.int16)
    expected = [int(correlate(window, patch, mask=mask, mean_compensation=mode)[0, 0]) for window in placements]
    f, lifted, bias = patch_terms(patch, mask, mode)
    cycles = 200
    advances = [bool(pattern[c % len(pattern)]) if pattern else True for c in range(cycles)]
    taken = np.cumsum(advances)  # steps taken after each edge
    checked = []

    def window_of(index):
        return placements[index % len(placements)] if index >= 0 else np.zeros(patch_shape, np.int16)

    async def bench(ctx):
        ctx.set(lane.patch_valid, int(sum(1 << x for x, valid in enumerate(mask.flat) if valid)))
        for x, value in enumerate(lifted):
            ctx.set(lane.lifted_patch[x], value)
        ctx.set(lane.mean_compensation, mode)
        ctx.set(lane.factor, f)
        ctx.set(lane.dividend_bias, bias)
        await ctx.tick().repeat(2)  # the lane's copies of the mode and f
        count = 0
        for c in range(cycles):
            # Before the edge: the step's window at the top, the one D steps older at the bottom.
            for l in range(w):
                for k in range(h):
                    ctx.set(lane.sum_window[l][k], int(window_of(count)[k, l]))
                    ctx.set(lane.term_window[l][k], int(window_of(count - D)[k, l]))
            ctx.set(lane.advance, advances[c])
            await ctx.tick()
            count = int(taken[c])
            # After edge c the value is that of the placement the bottom showed after edge c - T.
            if c >= T and taken[c - T] - D >= 0:
                index = int(taken[c - T]) - D
                assert ctx.get(lane.value) == expected[index % len(placements)], (c, index)
                checked.append(index)

    simulate(lane, bench)
    assert len(set(checked)) >= 8  # most placements were seen, not just one held value


@pytest.mark.parametrize("patch_shape, mode", [((3, 4), True), ((2, 2), False), ((1, 1), True)])
def test_patch_preparation_forms_the_lanes_terms_in_hw_plus_3_cycles(patch_shape, mode):
    h, w = patch_shape
    rng = np.random.default_rng([h, w, int(mode)])
    params = CorrelatorParameters(map_shape=(4, 5), patch_shape=patch_shape, depth_bits=B, lanes=1)
    dut = PatchPreparation(parameters=params)
    patch = rng.integers(-(2**15), 2**15, size=patch_shape).astype(np.int16)
    mask = rng.random(patch_shape) < 0.6
    mask.flat[-1] = True
    f, lifted, bias = patch_terms(patch, mask, mode)
    result = {}

    async def bench(ctx):
        ctx.set(dut.accept, 1)
        ctx.set(dut.idle, 1)
        for depth, valid in zip(patch.flat, mask.flat):
            ctx.set(dut.patch_in.valid, 1)
            ctx.set(dut.patch_in.payload, {"depth": int(depth), "valid": bool(valid)})
            assert ctx.get(dut.patch_in.ready)
            await ctx.tick()
        ctx.set(dut.patch_in.valid, 0)
        ctx.set(dut.start, 1)
        ctx.set(dut.start_mode, mode)
        await ctx.tick()  # edge 0: the start beat
        ctx.set(dut.start, 0)
        ctx.set(dut.idle, 0)
        ctx.set(dut.accept, 0)
        edge = 0
        while not ctx.get(dut.done):
            await ctx.tick()
            edge += 1
        await ctx.tick()
        result.update(done_edge=edge + 1, factor=ctx.get(dut.factor), bias=ctx.get(dut.dividend_bias),
                      lifted=[ctx.get(dut.lifted_patch[x]) for x in range(h * w)], valid=ctx.get(dut.patch_valid),
                      mode=ctx.get(dut.mean_compensation))

    simulate(dut, bench)
    assert result["done_edge"] == h * w + 3
    assert (result["factor"], result["bias"], result["mode"]) == (f, bias, int(mode))
    assert result["lifted"] == lifted
    assert result["valid"] == sum(1 << x for x, valid in enumerate(mask.flat) if valid)


def test_patch_preparation_lane_copies_equal_the_valid_bits_every_cycle():
    """Each lane's copy of the valid bits equals them on every cycle: loading, a pass, a reset (both persist)."""
    h, w, lanes = 3, 4, 3
    rng = np.random.default_rng(17)
    params = CorrelatorParameters(map_shape=(4, 5), patch_shape=(h, w), depth_bits=B, lanes=lanes)
    dut = PatchPreparation(parameters=params)
    top = Module()
    top.domains.sync = sync = ClockDomain()
    top.submodules.dut = dut
    seen = []

    async def check(ctx):
        valid = ctx.get(dut.patch_valid)
        assert [ctx.get(dut.lane_patch_valid[q]) for q in range(lanes)] == [valid] * lanes
        seen.append(valid)

    async def bench(ctx):
        ctx.set(dut.idle, 1)
        for cycle in range(4 * h * w):
            ctx.set(dut.accept, int(rng.random() < 0.8))
            ctx.set(dut.patch_in.valid, int(rng.random() < 0.7))
            ctx.set(dut.patch_in.payload, {"depth": int(rng.integers(-100, 100)), "valid": bool(rng.random() < 0.5)})
            ctx.set(sync.rst, int(cycle == 2 * h * w))
            await ctx.tick()
            await check(ctx)
        ctx.set(dut.patch_in.valid, 0)
        ctx.set(dut.start, 1)
        await ctx.tick()
        ctx.set(dut.start, 0)
        ctx.set(dut.idle, 0)
        for _ in range(h * w + 4):
            await ctx.tick()
            await check(ctx)

    sim = Simulator(top)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    assert len(set(seen)) > 5  # the bits changed many times, so the copies followed them


def test_credit_queue_keeps_order_and_counts_credits():
    depth = 5
    dut = CreditQueue(shape=8, depth=depth)
    rng = np.random.default_rng(3)
    received, sent = [], []

    async def bench(ctx):
        ctx.set(dut.clear, 1)
        await ctx.tick()
        ctx.set(dut.clear, 0)
        credits, queued, value = depth, 0, 0
        write = False  # decided a cycle ahead: the queue takes the write's next value too (write_next)
        for _ in range(300):
            issue = bool(credits) and rng.random() < 0.7
            # A beat may be written only against a credit taken earlier and not yet returned.
            in_flight = depth - credits - queued
            passed = in_flight - write > 0 and not write and rng.random() < 0.2
            write_next = in_flight + issue - write - passed > 0 and rng.random() < 0.5
            ready = rng.random() < 0.6
            assert ctx.get(dut.has_credit) == (credits != 0)
            ctx.set(dut.issue, issue)
            ctx.set(dut.write.valid, write)
            ctx.set(dut.write_next, write_next)
            ctx.set(dut.write.payload, value)
            ctx.set(dut.passed, passed)
            ctx.set(dut.surface.ready, ready)
            leaving = ctx.get(dut.surface.valid) and ready
            if leaving:
                received.append(ctx.get(dut.surface.payload))
            if write:
                sent.append(value)
                value = (value + 1) % 256
            await ctx.tick()
            credits += -issue + passed + leaving
            queued += write - leaving
            write = write_next

    simulate(dut, bench)
    assert len(received) > 50 and received == sent[:len(received)]


@pytest.mark.parametrize("lanes, width, rows, pattern", [(2, 4, 3, [1, 0, 1]), (1, 5, 2, [1]), (3, 4, 4, [1, 1, 0])])
def test_step_window_holds_each_steps_columns(lanes, width, rows, pattern):
    groups = -(-width // lanes)
    span = 3 * lanes
    height = rows + 3
    dut = StepWindow(lanes=lanes, rows=rows, groups=groups, span=span, depth_bits=B)
    terrain = np.random.default_rng(lanes).integers(-(2**15), 2**15, size=(height, groups * lanes)).astype(np.int16)
    steps = height * groups
    checked = []

    async def bench(ctx):
        taken, c = 0, 0
        while taken < steps:
            advance = bool(pattern[c % len(pattern)])
            r, g = divmod(taken, groups)
            for q in range(lanes):
                ctx.set(dut.word[q], int(terrain[r, g * lanes + q]))
            ctx.set(dut.group, g)
            ctx.set(dut.next_group, (g + 1) % groups)
            ctx.set(dut.is_word, 1)
            ctx.set(dut.advance, advance)
            await ctx.tick()
            taken += advance
            c += 1
            # After the edge of step ``taken - 1``, step ``taken - 2 - a`` is ``a`` steps of L columns from the right.
            for a in range(span // lanes):
                step = taken - 2 - a
                if step < 0:
                    continue
                r, g = divmod(step, groups)
                if r < rows - 1:
                    continue  # the line buffers do not hold rows above the map yet
                for q in range(lanes):
                    column = [ctx.get(dut.columns[span - lanes * (a + 1) + q][k]) for k in range(rows)]
                    assert column == terrain[r - rows + 1:r + 1, g * lanes + q].tolist(), (step, q)
                    checked.append(step)

    simulate(dut, bench)
    assert len(set(checked)) >= steps - (rows - 1) * groups - 2


def test_component_parameters_are_checked():
    with pytest.raises(ValueError, match="parameters must be a CorrelatorParameters"):
        WindowLane(parameters=(3, 3))
    with pytest.raises(ValueError, match="span must hold"):
        StepWindow(lanes=4, rows=2, groups=2, span=3, depth_bits=B)
    with pytest.raises(ValueError, match="depth must be a positive integer"):
        CreditQueue(shape=8, depth=0)
