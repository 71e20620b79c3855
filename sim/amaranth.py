"""Async testbench functions for the Amaranth simulator, shared by every gateware test.

Streams follow ``amaranth.lib.stream``: a beat transfers on a clock edge where ``valid`` and
``ready`` are both high. Values cross these functions as plain Python (ints, dicts and lists, see
:func:`lost.hdl.interface.decode_payload`), so tests compare them directly with :mod:`lost.model`.
Idle patterns are iterables of truthy/falsy flags, one per cycle (e.g. ``itertools.cycle([1, 1, 0])``):
a falsy flag keeps ``valid`` (sources) or ``ready`` (sinks) low for that cycle, as cocotbext-axi does.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable
from typing import Any

import numpy as np
from amaranth.hdl import ClockDomain, Module, ShapeCastable
from amaranth.lib import data
from amaranth.sim import Simulator

from lost.hdl.interface import comparable_best, decode_payload
from lost.model.cycles import surface_beats

__all__ = ["CorrelatorBench", "drain", "feed", "record_transfers", "stream_get", "stream_put", "to_python"]


def to_python(shape: Any, value: Any) -> Any:
    """A sampled payload (an int or a :class:`data.Const`) as plain Python values."""
    if isinstance(value, data.Const):
        return decode_payload(shape, value.as_bits())
    if isinstance(shape, ShapeCastable):
        return decode_payload(shape, int(value))
    return int(value)


async def stream_put(ctx, stream, payload) -> None:
    """Offer one beat and wait until it transfers; ``valid`` is low again afterwards."""
    ctx.set(stream.payload, payload)
    ctx.set(stream.valid, 1)
    await ctx.tick().until(stream.ready)
    ctx.set(stream.valid, 0)


async def stream_get(ctx, stream) -> Any:
    """Accept one beat and return its payload as plain Python values; ``ready`` is low afterwards."""
    ctx.set(stream.ready, 1)
    (payload,) = await ctx.tick().sample(stream.payload).until(stream.valid)
    ctx.set(stream.ready, 0)
    return to_python(stream.payload.shape(), payload)


async def feed(ctx, stream, payloads: Iterable, *, pattern: Iterable | None = None) -> None:
    """Send every payload in order, holding ``valid`` low on the cycles ``pattern`` marks idle."""
    pattern = iter(pattern if pattern is not None else itertools.repeat(1))
    for payload in payloads:
        while not next(pattern):
            await ctx.tick()
        await stream_put(ctx, stream, payload)


async def drain(ctx, stream, count: int, *, pattern: Iterable | None = None) -> list:
    """Receive ``count`` beats in order, holding ``ready`` low on the cycles ``pattern`` marks idle."""
    pattern = iter(pattern if pattern is not None else itertools.repeat(1))
    received = []
    while len(received) < count:
        ready = bool(next(pattern))
        ctx.set(stream.ready, ready)
        _, _, valid, payload = await ctx.tick().sample(stream.valid, stream.payload)
        if ready and valid:
            received.append(to_python(stream.payload.shape(), payload))
    ctx.set(stream.ready, 0)
    return received


async def record_transfers(ctx, stream, log: list) -> None:
    """Append ``(edge, payload)`` to ``log`` for every beat that transfers, forever.

    ``edge`` counts the clock's rising edges from the start of the simulation (the first edge is 0),
    so two logs of one simulation share a time base. Run it as a background testbench
    (``sim.add_testbench(..., background=True)``); it only samples, never drives.
    """
    shape = stream.payload.shape()
    async for edge, (_, reset, valid, ready, payload) in _enumerate(
            ctx.tick().sample(stream.valid, stream.ready, stream.payload)):
        if valid and ready and not reset:
            log.append((edge, to_python(shape, payload)))


async def _enumerate(aiterable):
    edge = 0
    async for item in aiterable:
        yield edge, item
        edge += 1


class CorrelatorBench:
    """A correlator core (either variant) in a module with an explicit sync domain (so tests can reset
    it), with transfer logs of start, surface and best, and busy sampled on every edge."""

    def __init__(self, dut):
        self.dut = dut
        self.parameters = self.dut.parameters
        self.top = Module()
        self.top.domains.sync = self.domain = ClockDomain("sync")
        self.top.submodules.dut = self.dut
        self.logs = {"start": [], "surface": [], "best": []}
        self.sim = Simulator(self.top)
        self.sim.add_clock(1e-8)
        for name, log in self.logs.items():
            self.sim.add_testbench(self._monitor(getattr(self.dut, name), log), background=True)
        self.busy = []  # busy as sampled on every edge, edge 0 first
        self.sim.add_testbench(self._sample_busy, background=True)

    async def _sample_busy(self, ctx):
        async for _, _, busy in ctx.tick().sample(self.dut.busy):
            self.busy.append(busy)

    @staticmethod
    def _monitor(stream, log):
        async def monitor(ctx):
            await record_transfers(ctx, stream, log)
        return monitor

    async def load(self, ctx, *, terrain=None, patch=None, mask=None, pattern=None):
        if terrain is not None:
            await feed(ctx, self.dut.map_in, terrain.ravel().tolist(), pattern=pattern)
        if patch is not None:
            words = [{"depth": int(d), "valid": int(v)} for d, v in zip(patch.ravel(), mask.ravel())]
            await feed(ctx, self.dut.patch_in, words, pattern=pattern)

    async def correlate(self, ctx, *, mean_compensation, surface_pattern=None, best_pattern=None):
        """Run one correlation; check the beats' order and flags; return the surface and best beat."""
        beat_plan = surface_beats(self.parameters.surface_shape, self.parameters.lanes)
        await feed(ctx, self.dut.start, [{"mean_compensation": int(mean_compensation)}])
        beats = await drain(ctx, self.dut.surface, len(beat_plan), pattern=surface_pattern)
        (best,) = await drain(ctx, self.dut.best, 1, pattern=best_pattern)
        assert [(b["i"], b["j"], b["count"], b["last"]) for b in beats] == [
            (i, j, count, int(k == len(beat_plan) - 1)) for k, (i, j, count) in enumerate(beat_plan)]
        surface = np.zeros(self.parameters.surface_shape, dtype=np.int64)
        for beat in beats:
            surface[beat["i"], beat["j"]:beat["j"] + beat["count"]] = beat["values"][:beat["count"]]
            # Lanes past the row's end carry no placement; they must not leak stale values.
            assert beat["values"][beat["count"]:] == [0] * (self.parameters.lanes - beat["count"])
        return surface, comparable_best(best)

    def cycles(self, run):
        """Surface and best cycles of the ``run``-th correlation, counted from its start beat."""
        start = self.logs["start"][run][0]
        beats = len(surface_beats(self.parameters.surface_shape, self.parameters.lanes))
        surface = [edge - start for edge, _ in self.logs["surface"][run * beats:(run + 1) * beats]]
        return surface, self.logs["best"][run][0] - start

    def run(self, testbench):
        self.sim.add_testbench(testbench)
        self.sim.run()
