# amaranth: UnusedElaboratable=no
"""MapSequencer: every word and tag, in order, under random request gaps and response stalls."""

import itertools

import numpy as np
import pytest
from amaranth.hdl import Module, signed, unsigned
from amaranth.lib import memory, wiring
from amaranth.sim import Simulator

from lost.hdl.sequencer import MapSequencer
from lost.sim.amaranth import drain, feed, record_transfers

DEPTH = 37
ADDR_WIDTH = 6


def simulate(words, requests, *, source_pattern=None, sink_pattern=None):
    """Run ``requests`` (addr, tag) through a sequencer on a memory holding ``words``."""
    sequencer = MapSequencer(addr_width=ADDR_WIDTH, shape=signed(16), tag_shape=unsigned(8))
    m = Module()
    m.submodules.sequencer = sequencer
    m.submodules.storage = storage = memory.Memory(shape=signed(16), depth=DEPTH, init=words)
    wiring.connect(m, sequencer.read, storage.read_port())

    received, requested = [], []

    async def source(ctx):
        await feed(ctx, sequencer.request, [{"addr": a, "tag": t} for a, t in requests], pattern=source_pattern)

    async def sink(ctx):
        received.extend(await drain(ctx, sequencer.response, len(requests), pattern=sink_pattern))

    async def monitor(ctx):
        await record_transfers(ctx, sequencer.request, requested)

    sim = Simulator(m)
    sim.add_clock(1e-8)
    sim.add_testbench(source)
    sim.add_testbench(sink)
    sim.add_testbench(monitor, background=True)
    sim.run()
    return received, requested


@pytest.mark.parametrize("seed", range(4))
def test_every_word_under_random_gaps(seed):
    rng = np.random.default_rng(seed)
    words = [int(w) for w in rng.integers(-(2**15), 2**15, DEPTH)]
    requests = [(int(a), int(t)) for a, t in zip(rng.integers(0, DEPTH, 300), rng.integers(0, 256, 300))]
    source_pattern = (bool(x) for x in rng.random(10_000) < 0.7)
    sink_pattern = (bool(x) for x in rng.random(10_000) < [0.3, 0.6, 0.9, 1.0][seed])
    received, _ = simulate(words, requests, source_pattern=source_pattern, sink_pattern=sink_pattern)
    assert received == [{"data": words[a], "tag": t} for a, t in requests]


@pytest.mark.parametrize("sink_pattern", [[1, 0], [0, 0, 1], [1, 1, 1, 0], [0, 1, 1]])
def test_every_word_under_periodic_stalls(sink_pattern):
    words = list(range(-18, 19))
    requests = [((7 * k) % DEPTH, k % 256) for k in range(120)]
    received, _ = simulate(words, requests, sink_pattern=itertools.cycle(sink_pattern))
    assert received == [{"data": words[a], "tag": t} for a, t in requests]


def test_one_word_per_cycle_without_stalls():
    words = list(range(DEPTH))
    requests = [(k % DEPTH, k % 256) for k in range(100)]
    received, requested = simulate(words, requests)
    assert received == [{"data": a, "tag": t} for a, t in requests]
    edges = [edge for edge, _ in requested]
    assert edges == list(range(edges[0], edges[0] + len(requests)))


def test_rejects_bad_parameters():
    with pytest.raises(ValueError, match="addr_width"):
        MapSequencer(addr_width=-1, shape=signed(16))
    with pytest.raises(ValueError, match="shape"):
        MapSequencer(addr_width=4, shape="sixteen")
