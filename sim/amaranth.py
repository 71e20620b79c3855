"""Async testbench helpers for the Amaranth simulator, shared by every gateware test.

Streams follow ``amaranth.lib.stream``: a beat transfers on a clock edge where ``valid`` and
``ready`` are both high. Values cross these helpers as plain Python (ints, dicts and lists, see
:func:`lost.hdl.interface.decode_payload`), so tests compare them directly with :mod:`lost.model`.
Idle patterns are iterables of truthy/falsy flags, one per cycle (e.g. ``itertools.cycle([1, 1, 0])``):
a falsy flag keeps ``valid`` (sources) or ``ready`` (sinks) low for that cycle, as cocotbext-axi does.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable
from typing import Any

from amaranth.hdl import ShapeCastable
from amaranth.lib import data

from lost.hdl.interface import decode_payload

__all__ = ["drain", "feed", "record_transfers", "stream_get", "stream_put", "to_python"]


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
