# amaranth: UnusedElaboratable=no
"""RunnerUpScan alone against a NumPy model: the smallest candidate outside the best fit's zone, at its latency."""

import numpy as np
import pytest
from amaranth.hdl import Module
from amaranth.lib import memory, wiring
from amaranth.sim import Simulator

from lost.hdl.interface import CorrelatorParameters
from lost.hdl.reducer_scan import RunnerUpScan, row_minimum_layout


@pytest.mark.parametrize("surface_shape, lanes, radius", [((9, 11), 1, 1), ((12, 10), 4, 2), ((5, 7), 3, 3), ((3, 4), 2, 0)])
def test_the_runner_up_is_the_smallest_candidate_outside_the_zone(surface_shape, lanes, radius):
    rows, cols = surface_shape
    rng = np.random.default_rng([rows, cols, lanes, radius])
    params = CorrelatorParameters(map_shape=(rows + 1, cols + 1), patch_shape=(2, 2), lanes=lanes, exclusion_radius=radius)
    scan = RunnerUpScan(parameters=params)
    slots, beats = scan.slots, scan.beats_per_row
    bi, bj = int(rng.integers(rows)), int(rng.integers(cols))
    values = rng.integers(1, 50, size=(rows, cols))  # small values: many ties, broken by raster order
    # The zone around the best fit holds the smallest values: a zone one node too small would pick one.
    values[max(bi - radius, 0):bi + radius + 1, max(bj - radius, 0):bj + radius + 1] = 0
    minima = [(int(values[i].min()), int(values[i].argmin())) for i in range(rows)]
    band = [i for i in range(max(bi - radius, 0), min(bi + radius, rows - 1) + 1)]
    held = rng.permutation(band)[:slots].tolist() + [None] * max(slots - len(band), 0)
    in_band = [row is not None and bool(rng.random() < 0.8) for row in held]
    words = np.zeros((slots * beats, lanes), dtype=np.int64)
    for s, row in enumerate(held):
        if row is not None:
            padded = np.concatenate([values[row], np.zeros(beats * lanes - cols, dtype=np.int64)])
            words[s * beats:(s + 1) * beats] = padded.reshape(beats, lanes)
    candidates = [(v, i, c) for i, (v, c) in enumerate(minima) if abs(i - bi) > radius]
    candidates += [(int(values[row, j]), row, j) for row, ok in zip(held, in_band) if ok
                   for j in range(cols) if abs(j - bj) > radius]
    expected = min(candidates) if candidates else None

    m = Module()
    m.submodules.scan = scan
    m.submodules.minima = minima_memory = memory.Memory(
        shape=row_minimum_layout(params), depth=rows, init=[{"value": v, "col": c} for v, c in minima])
    m.submodules.slots = slots_memory = memory.Memory(
        shape=scan.values_layout, depth=slots * beats, init=[[int(x) for x in word] for word in words])
    wiring.connect(m, scan.minima_read, minima_memory.read_port())
    wiring.connect(m, scan.slots_read, slots_memory.read_port())
    result = {}

    async def bench(ctx):
        ctx.set(scan.best_i, bi)
        ctx.set(scan.best_j, bj)
        for s, row in enumerate(held):
            ctx.set(scan.slot_rows[s], 0 if row is None else row)
            ctx.set(scan.slot_in_band[s], in_band[s])
        await ctx.tick()
        ctx.set(scan.start, 1)
        await ctx.tick()  # edge 0
        ctx.set(scan.start, 0)
        edge = 0
        while not ctx.get(scan.done):
            await ctx.tick()
            edge += 1
            assert edge <= scan.latency
        runner = scan.runner
        result.update(edge=edge, valid=ctx.get(runner.valid), runner=(ctx.get(runner.value), ctx.get(runner.i), ctx.get(runner.j)))

    sim = Simulator(m)
    sim.add_clock(1e-8)
    sim.add_testbench(bench)
    sim.run()
    assert result["edge"] == scan.latency == rows + slots * beats + int(np.ceil(np.log2(lanes))) + 3
    assert result["valid"] == (expected is not None)
    if expected is not None:
        assert result["runner"] == expected
