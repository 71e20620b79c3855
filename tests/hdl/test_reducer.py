# amaranth: UnusedElaboratable=no
"""BestFitReducer against lost.model.best_fit: ties, runner-up ties, edges, covering radii, lanes."""


import numpy as np
import pytest
from amaranth.sim import Simulator

from lost.hdl.interface import CorrelatorParameters, best_fit_payload, comparable_best
from lost.hdl.reducer import BestFitReducer
from lost.model import best_fit
from lost.model.cycles import reducer_latency, surface_beats
from lost.sim.amaranth import feed, record_transfers, stream_get


def parameters_for(surface_shape, *, lanes, radius):
    # A 1 x 2 patch gives 18-bit values; the map is sized so the surface has the wanted shape.
    rows, cols = surface_shape
    return CorrelatorParameters(map_shape=(rows, cols + 1), patch_shape=(1, 2), lanes=lanes,
                                exclusion_radius=radius)


def beats_of(surface, lanes):
    rows, cols = surface.shape
    beats = []
    for i, j, count in surface_beats(surface.shape, lanes):
        values = [int(v) for v in surface[i, j:j + count]] + [0] * (lanes - count)
        beats.append({"values": values, "count": count, "i": i, "j": j, "last": 0})
    beats[-1]["last"] = 1
    return beats






def simulate(surfaces, *, lanes, radius, source_pattern=None, sink_idle=0):
    """Reduce several surfaces of one shape in a row; return the best beats and the transfer edges."""
    reducer = BestFitReducer(parameters=parameters_for(surfaces[0].shape, lanes=lanes, radius=radius))
    results, beat_log, best_log = [], [], []

    async def testbench(ctx):
        for surface in surfaces:
            await feed(ctx, reducer.surface, beats_of(surface, lanes), pattern=source_pattern)
            if sink_idle:
                await ctx.tick().repeat(sink_idle)
            results.append(comparable_best(await stream_get(ctx, reducer.best)))

    async def surface_monitor(ctx):
        await record_transfers(ctx, reducer.surface, beat_log)

    async def best_monitor(ctx):
        await record_transfers(ctx, reducer.best, best_log)

    sim = Simulator(reducer)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.add_testbench(surface_monitor, background=True)
    sim.add_testbench(best_monitor, background=True)
    sim.run()
    return results, beat_log, best_log


def random_surface(rng, shape, *, high):
    return rng.integers(0, high, shape).astype(np.int64)


@pytest.mark.parametrize("lanes", [1, 3, 4, 8])  # lane trees of 0, 2 (uneven), 2 and 3 levels
@pytest.mark.parametrize("radius", [0, 1, 2])
def test_random_surfaces_with_ties(lanes, radius):
    rng = np.random.default_rng(100 * lanes + radius)
    shape = (7, 10)  # 10 columns: lanes = 4 leaves a partial last beat in every row
    # Few distinct values: many ties for the best and for the runner-up.
    surfaces = [random_surface(rng, shape, high=high) for high in (3, 6, 40, 2**18)]
    results, _, _ = simulate(surfaces, lanes=lanes, radius=radius,
                             source_pattern=(bool(x) for x in rng.random(10_000) < 0.8))
    assert results == [best_fit_payload(best_fit(surface, exclusion_radius=radius)) for surface in surfaces]


@pytest.mark.parametrize("lanes", [1, 4])
def test_best_at_corners_and_edges(lanes):
    rng = np.random.default_rng(7)
    shape = (6, 9)
    surfaces = []
    for i, j in [(0, 0), (0, 8), (5, 0), (5, 8), (0, 4), (5, 4), (2, 0), (3, 8)]:
        surface = random_surface(rng, shape, high=1000) + 10
        surface[i, j] = 1
        # A runner-up inside the exclusion zone must not count; one just outside must.
        surface[min(i + 1, 5), j] = 2
        surface[(i + 3) % 6, (j + 4) % 9] = 5
        surfaces.append(surface)
    results, _, _ = simulate(surfaces, lanes=lanes, radius=1)
    assert results == [best_fit_payload(best_fit(surface, exclusion_radius=1)) for surface in surfaces]


@pytest.mark.parametrize("lanes", [1, 4])
def test_later_best_moves_the_band(lanes):
    # A best late in the surface after an early one, and rows around both with small values:
    # the band held at the end must be the final best's.
    shape = (12, 7)
    surface = np.full(shape, 100, dtype=np.int64)
    surface[1, 3], surface[2, 4], surface[0, 0] = 5, 6, 7
    surface[10, 2], surface[9, 2], surface[11, 6], surface[9, 0] = 3, 9, 8, 8
    surfaces = [surface, surface[::-1].copy(), surface[:, ::-1].copy()]
    results, _, _ = simulate(surfaces, lanes=lanes, radius=2)
    assert results == [best_fit_payload(best_fit(s, exclusion_radius=2)) for s in surfaces]


@pytest.mark.parametrize(("shape", "radius"), [((3, 4), 3), ((3, 4), 5), ((1, 1), 0), ((1, 6), 1), ((5, 1), 1), ((2, 2), 1)])
def test_small_surfaces_and_covering_radii(shape, radius):
    rng = np.random.default_rng(sum(shape) + radius)
    surfaces = [random_surface(rng, shape, high=4) for _ in range(3)]
    for lanes in (1, 4):
        results, _, _ = simulate(surfaces, lanes=lanes, radius=radius)
        assert results == [best_fit_payload(best_fit(surface, exclusion_radius=radius)) for surface in surfaces]


@pytest.mark.parametrize("lanes", [1, 3, 5, 8])
def test_latency_matches_the_cycle_model(lanes):
    rng = np.random.default_rng(lanes)
    shape = (8, 11)
    surfaces = [random_surface(rng, shape, high=50) for _ in range(2)]
    results, beat_log, best_log = simulate(surfaces, lanes=lanes, radius=1)
    assert results == [best_fit_payload(best_fit(surface, exclusion_radius=1)) for surface in surfaces]
    last_edges = [edge for edge, beat in beat_log if beat["last"]]
    best_edges = [edge for edge, _ in best_log]
    latency = reducer_latency(shape, lanes, 1)
    assert [b - l for l, b in zip(last_edges, best_edges)] == [latency, latency]


def test_best_beat_waits_for_ready():
    rng = np.random.default_rng(11)
    surfaces = [random_surface(rng, (5, 6), high=9) for _ in range(3)]
    results, _, best_log = simulate(surfaces, lanes=2, radius=1, sink_idle=80)
    assert results == [best_fit_payload(best_fit(surface, exclusion_radius=1)) for surface in surfaces]
    assert len(best_log) == 3


def test_busy_from_the_last_beat_until_the_best_beat():
    # A core starts its next correlation only when the reducer is idle: busy must not drop early.
    rng = np.random.default_rng(21)
    surface = random_surface(rng, (4, 5), high=30)
    reducer = BestFitReducer(parameters=parameters_for(surface.shape, lanes=2, radius=1))
    trace = []

    async def testbench(ctx):
        await feed(ctx, reducer.surface, beats_of(surface, 2))
        ctx.set(reducer.best.ready, 1)
        while True:
            _, _, busy, valid = await ctx.tick().sample(reducer.busy, reducer.best.valid)
            trace.append(busy)
            if valid:
                break
        await ctx.tick()
        trace.append(ctx.get(reducer.busy))

    sim = Simulator(reducer)
    sim.add_clock(1e-8)
    sim.add_testbench(testbench)
    sim.run()
    # Sampled on every edge from the one after the last beat to the best beat's transfer, then after it.
    assert len(trace) == reducer_latency(surface.shape, 2, 1) + 1
    assert trace[:-1] == [1] * (len(trace) - 1) and trace[-1] == 0


def test_rejects_bad_parameters():
    with pytest.raises(ValueError, match="CorrelatorParameters"):
        BestFitReducer(parameters={"map_shape": (4, 4)})


@pytest.mark.parametrize("lanes", [1, 4])
@pytest.mark.parametrize("radius", [1, 2])
def test_runner_up_in_the_band_rows_before_a_late_best(lanes, radius):
    # The runner-up sits in a row just before (or after) the final best row, far from its column, and
    # earlier rows held a provisional best: only the rolling rows keep it.
    rng = np.random.default_rng(31 * lanes + radius)
    shape = (11, 9)
    surfaces = []
    for _ in range(8):
        surface = random_surface(rng, shape, high=100) + 1000
        best_row = int(rng.integers(radius + 2, shape[0]))
        best_col = int(rng.integers(0, shape[1]))
        surface[int(rng.integers(0, best_row - radius)), int(rng.integers(0, shape[1]))] = 500  # provisional best
        surface[best_row, best_col] = 1
        runner_row = best_row + int(rng.choice([k for k in range(-radius, radius + 1) if k]))
        runner_row = min(runner_row, shape[0] - 1)
        runner_col = (best_col + radius + 1 + int(rng.integers(0, shape[1] - 2 * radius - 1))) % shape[1]
        surface[runner_row, runner_col] = 2
        surfaces.append(surface)
    results, _, _ = simulate(surfaces, lanes=lanes, radius=radius)
    assert results == [best_fit_payload(best_fit(surface, exclusion_radius=radius)) for surface in surfaces]
